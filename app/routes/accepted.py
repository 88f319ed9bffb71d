"""What the two submission routes (a job, a batch) share: the Idempotency-Key header and the
202 answer's headers."""

from __future__ import annotations

from typing import Annotated

from fastapi import Header, Response

IdempotencyKey = Annotated[
    str | None,
    Header(
        alias="Idempotency-Key",
        description="The same key and body return the same job (or batch) with "
        "Idempotent-Replayed: true; the same key with another body: 422.",
    ),
]


def accepted(response: Response, location: str, replayed: bool) -> None:
    """Point the 202 answer at the new (or replayed) resource."""
    response.headers["Location"] = location
    if replayed:
        response.headers["Idempotent-Replayed"] = "true"
