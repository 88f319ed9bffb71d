"""A chained batch's child starts from the answer of its nearest sibling finished by then: its
stored problem gains that sibling's trajectory as ``initial_guess`` for this attempt."""

from __future__ import annotations

import logging
from typing import Any

from app.batch_plan import nearest
from app.schemas.guess import guess_columns
from app.storage import repository
from app.storage.session import Database

log = logging.getLogger(__name__)


def with_sibling_guess(
    database: Database, batch_id: str, parameters: dict[str, Any], problem: dict[str, Any]
) -> dict[str, Any]:
    """``problem`` starting from the nearest finished sibling's trajectory, when the batch
    chains its children and there is one; else ``problem`` as it is. A problem that already
    has an initial guess keeps it."""
    if problem.get("initial_guess") is not None:
        return problem
    with database.reader() as session:
        if not repository.chained_batch(session, batch_id):
            return problem
        sibling = nearest(parameters, repository.finished_siblings(session, batch_id))
        trajectory = repository.job_trajectory(session, sibling) if sibling else None
    if trajectory is None:
        return problem
    columns = guess_columns(trajectory)
    if columns is None:
        return problem
    log.info("batch %s: starting from sibling %s", batch_id, sibling)
    return {**problem, "initial_guess": {"from_job": sibling, "trajectory": columns}}
