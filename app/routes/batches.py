"""``/v1/batches``: many jobs on one base problem (a grid of parameter values, a Monte Carlo
dispersion, a method comparison), followed and summarized as one."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, BackgroundTasks, Query, Response
from starlette.concurrency import run_in_threadpool

from app import batches_service
from app.body import ProblemBody
from app.deps import DatabaseDep, DispatcherDep, OwnerDep, ServiceDep, SettingsDep, SubmitterDep
from app.report import PLOT_FORMATS
from app.report.batch import render_summary_plot
from app.routes.accepted import IdempotencyKey, accepted
from app.routes.report import RENDER_ERRORS, plot_media_type
from app.views import BatchPage, BatchSummary, BatchView, ErrorResponse

router = APIRouter(prefix="/v1/batches", tags=["batches"])

_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": ErrorResponse}}

BATCH_EXAMPLES: dict[str, dict[str, Any]] = {
    "grid": {
        "summary": "a zone radius x a heat-rate limit (20 children)",
        "value": {
            "name": "zone and heating",
            "base": {"scenario": "rlv-max-terminal-velocity-active-nfz"},
            "grid": {
                "parameters": [
                    {"path": "/no_fly_zones/0/radius_deg", "values": [1.0, 1.5, 2.0, 2.5, 3.0]},
                    {
                        "path": "/path_constraints/heat_rate/max_W_m2",
                        "values": [1.4e6, 1.5e6, 1.6e6, 1.7e6],
                    },
                ]
            },
        },
    },
    "monte_carlo": {
        "summary": "dispersed entry speed and mass (reproducible with its seed)",
        "value": {
            "base": {"scenario": "rlv-min-heat-load", "method": {"nodes": 61}},
            "monte_carlo": {
                "samples": 20,
                "seed": 7,
                "dispersions": [
                    {"path": "/initial_state/velocity_m_s", "distribution": "normal", "sigma": 15},
                    {"path": "/vehicle/mass_kg", "distribution": "uniform", "half_width": 500},
                ],
            },
        },
    },
    "methods": {
        "summary": "one problem, two methods",
        "value": {
            "base": {"scenario": "rlv-max-terminal-velocity"},
            "methods": [{"name": "foh-ptr"}, {"name": "foh-ptr", "grid": "uniform"}],
        },
    },
}


@router.post(
    "",
    status_code=202,
    response_model=BatchView,
    summary="Submit a batch",
    responses={
        202: {"description": "Stored, children queued; poll the Location."},
        422: {"model": ErrorResponse, "description": "Every invalid field or child, or a cap."},
        429: {"model": ErrorResponse, "description": "Rate limit, or the active-job cap."},
    },
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {
                "application/json": {
                    "schema": {"$ref": "#/components/schemas/BatchRequest"},
                    "examples": BATCH_EXAMPLES,
                }
            },
        }
    },
)
def submit_batch(
    body: ProblemBody,
    response: Response,
    background: BackgroundTasks,
    database: DatabaseDep,
    dispatcher: DispatcherDep,
    settings: SettingsDep,
    owner: SubmitterDep,
    idempotency_key: IdempotencyKey = None,
) -> BatchView:
    """Validate the base problem and every child, store the batch and queue its children."""
    view, replayed = batches_service.submit_batch(
        database=database,
        dispatcher=dispatcher,
        settings=settings,
        owner=owner,
        body=body,
        idempotency_key=idempotency_key,
        defer=background.add_task,
    )
    accepted(response, view.links.self, replayed)
    return view


@router.get("", response_model=BatchPage, summary="List your batches")
def list_batches(
    database: DatabaseDep,
    owner: OwnerDep,
    limit: Annotated[int, Query(ge=1, le=100)] = 20,
    offset: Annotated[int, Query(ge=0, le=1_000_000_000)] = 0,
) -> BatchPage:
    """The caller's batches, newest first."""
    return batches_service.list_batches(database, owner, limit, offset)


@router.get("/{batch_id}", response_model=BatchView, responses=_NOT_FOUND, summary="Show a batch")
def get_batch(batch_id: str, database: DatabaseDep, owner: OwnerDep) -> BatchView:
    """Status and the children counted by job status."""
    return batches_service.get_batch(database, owner, batch_id)


@router.delete(
    "/{batch_id}", response_model=BatchView, responses=_NOT_FOUND, summary="Cancel a batch"
)
def cancel_batch(batch_id: str, database: DatabaseDep, owner: OwnerDep) -> BatchView:
    """Cancel the children not finished yet (queued at once, running at their next iteration)."""
    return batches_service.cancel_batch(database, owner, batch_id)


@router.get(
    "/{batch_id}/summary",
    response_model=BatchSummary,
    responses=_NOT_FOUND,
    summary="The batch's summary table",
)
def get_summary(batch_id: str, database: DatabaseDep, owner: OwnerDep) -> BatchSummary:
    """One row per child: parameters, status, objective, terminal and path figures, time."""
    return batches_service.summary(database, owner, batch_id)


@router.get(
    "/{batch_id}/summary.csv",
    response_class=Response,
    responses={200: {"content": {"text/csv": {"schema": {"type": "string"}}}}, **_NOT_FOUND},
    summary="The batch's summary table as CSV",
)
def get_summary_csv(batch_id: str, database: DatabaseDep, owner: OwnerDep) -> Response:
    """The summary, a row per child, a column per parameter path and figure."""
    return Response(
        batches_service.summary_table(database, owner, batch_id),
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="{batch_id}-summary.csv"'},
    )


@router.get(
    "/{batch_id}/plot.{fmt}",
    response_class=Response,
    responses={
        200: {"content": {media: {} for media in PLOT_FORMATS.values()}},
        **_NOT_FOUND,
        **RENDER_ERRORS,
    },
    summary="The batch's plot (PNG or SVG)",
)
async def get_plot(batch_id: str, fmt: str, service: ServiceDep, owner: OwnerDep) -> Response:
    """Objective against the grid's parameters, the dispersed runs' terminal points, or the
    methods side by side. Kept until one of the batch's children changes; rendered like a job's
    plots (in a render process, one of the client's plots at a time)."""
    media_type = plot_media_type(fmt)
    database = service.database
    state = await run_in_threadpool(batches_service.plot_state, database, owner, batch_id)

    async def prepare() -> tuple[Any, ...]:
        kind, rows, paths, tracks = await run_in_threadpool(
            batches_service.plot_inputs, database, owner, batch_id
        )
        return kind, rows, paths, fmt, tracks

    image = await service.renders.render(
        owner, ("batch", batch_id, fmt, state), render_summary_plot, prepare=prepare
    )
    return Response(image, media_type=media_type)
