"""``GET /v1/jobs/{id}/events``: live convergence as server-sent events."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Header
from sse_starlette.sse import EventSourceResponse

from app import jobs_service
from app.deps import OwnerDep, ServiceDep
from app.events import job_events, parse_last_event_id
from app.storage.models import Job
from app.views import ErrorResponse

router = APIRouter(prefix="/v1/jobs", tags=["jobs"])

SSE_DESCRIPTION = """\
A `text/event-stream`. One `iteration` event per SCP iteration (data: the iteration's history
record plus `job_id` and `attempt`; id: the iteration count), then one `end` event whose data is
the finished job. A client reconnecting with `Last-Event-ID: n` gets iterations after n.
"""


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
    },
)
def stream_events(
    job_id: str,
    service: ServiceDep,
    owner: OwnerDep,
    last_event_id: Annotated[str | None, Header(alias="Last-Event-ID")] = None,
) -> EventSourceResponse:
    """Events of one job until it ends (404 if there is no such job)."""
    database, settings = service.database, service.settings
    jobs_service.get_job(database, settings, owner, job_id)  # 404 before the stream starts

    def end_payload(job: Job) -> Any:
        return jobs_service.job_view(job, settings).model_dump(mode="json")

    events = job_events(
        database=database,
        waker=service.waker,
        job_id=job_id,
        owner=owner,
        end_payload=end_payload,
        after=parse_last_event_id(last_event_id),
    )
    return EventSourceResponse(
        events,
        ping=settings.event_ping_interval_s,
        send_timeout=30.0,
        headers={"Cache-Control": "no-store"},
    )
