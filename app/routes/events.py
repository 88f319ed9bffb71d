"""``GET /v1/jobs/{id}/events``: live convergence as server-sent events."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Header
from sse_starlette.sse import EventSourceResponse
from starlette.types import Receive, Scope, Send

from app import jobs_service
from app.deps import OwnerDep, ServiceDep
from app.events import parse_last_event_id
from app.storage.models import Job
from app.stream_hub import StreamSlot
from app.views import ErrorResponse

router = APIRouter(prefix="/v1/jobs", tags=["jobs"])

SSE_DESCRIPTION = """\
A `text/event-stream`. One `iteration` event per SCP iteration (data: the iteration's history
record plus `job_id` and `attempt`; id: the iteration count), then one `end` event whose data is
the finished job. A client reconnecting with `Last-Event-ID: n` gets iterations after n.

Open streams are capped per client and per server process (`TRAJOPT_MAX_STREAMS_PER_CLIENT`,
`TRAJOPT_MAX_STREAMS`): one more is refused with 429 `too_many_streams` and a Retry-After.
"""


class SlotResponse(EventSourceResponse):
    """An event stream that gives its admission slot back when the response ends, even if the
    client left before the first event (when the event generator never ran)."""

    def __init__(self, *args: Any, slot: StreamSlot, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.slot = slot

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Send the stream, then release the slot."""
        try:
            await super().__call__(scope, receive, send)
        finally:
            self.slot.release()


@router.get(
    "/{job_id}/events",
    summary="Stream convergence events",
    description=SSE_DESCRIPTION,
    response_class=EventSourceResponse,
    responses={
        200: {
            "content": {
                "text/event-stream": {
                    "example": 'event: iteration\nid: 1\ndata: {"job_id": "...", "attempt": 1, '
                    '"iteration": 1, "cost": 2.1e7, "conic_status": "optimal"}\n\n'
                    'event: end\nid: 2\ndata: {"id": "...", "status": "succeeded"}\n\n'
                }
            }
        },
        404: {"model": ErrorResponse},
        429: {
            "model": ErrorResponse,
            "description": "Rate limit, or too many open event streams (`too_many_streams`); "
            "retry after Retry-After.",
        },
    },
)
def stream_events(
    job_id: str,
    service: ServiceDep,
    owner: OwnerDep,
    last_event_id: Annotated[str | None, Header(alias="Last-Event-ID")] = None,
) -> EventSourceResponse:
    """Events of one job until it ends (429 over the stream caps, 404 if there is no such job)."""
    database, settings = service.database, service.settings
    slot = service.streams.admit(owner)  # before any database read: refusals cost nothing
    try:
        jobs_service.get_job(database, settings, owner, job_id)  # 404 before the stream starts
    except BaseException:
        slot.release()
        raise

    def end_payload(job: Job) -> Any:
        return jobs_service.job_view(job, settings).model_dump(mode="json")

    events = service.streams.events(
        job_id, slot=slot, end_payload=end_payload, after=parse_last_event_id(last_event_id)
    )
    return SlotResponse(
        events,
        slot=slot,
        ping=settings.event_ping_interval_s,
        send_timeout=30.0,
        headers={"Cache-Control": "no-store"},
    )
