"""Auto's budget counts CPU seconds, as every method's ``time_limit_s`` does: an attempt that
waits (wall-clock time, no CPU) leaves the next attempts their budget. Pure logic: the methods
are replaced by a function that sleeps and fails."""

from __future__ import annotations

import copy
import time
from typing import Any

from app.schemas import ProblemDocument
from app.schemas.methods import METHOD_OPTIONS
from worker.solver.auto.runner import MIN_ATTEMPT_S, AutoRun
from worker.solver.scenarios import get_scenario

LIMIT_S = 1.2
"""Auto's budget: above ``MIN_ATTEMPT_S`` (1 s), so a second attempt starts only when the first
one's 0.5 s of sleep is not counted against it."""


def _sleeping_failure(document: ProblemDocument, **hooks: Any) -> dict[str, Any]:
    time.sleep(0.5)
    return {"status": "failed", "history": [], "failure": {"code": "diverged"}}


def test_an_attempt_that_sleeps_leaves_the_next_its_cpu_budget() -> None:
    assert LIMIT_S > MIN_ATTEMPT_S
    document = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    document["method"] = {"time_limit_s": LIMIT_S}
    run = AutoRun(ProblemDocument.model_validate(document), _sleeping_failure, {})
    for name in ("foh-ptr", "cheb-scvx"):
        attempt = run.run(name, METHOD_OPTIONS[name].model_validate({"name": name}), "answer")
        assert attempt is not None, f"{name} not started: {run.left():.3f} s left"
        # 0.5 s of sleep used about no CPU time: the second attempt gets more than the 0.7 s a
        # wall-clock budget would leave, bounded by the wall-clock safety's share (4.3 s / 4)
        assert attempt.options["time_limit_s"] >= MIN_ATTEMPT_S, attempt.options["time_limit_s"]
    assert run.stop is None
