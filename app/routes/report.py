"""``/v1/jobs/{id}/trajectory.csv`` and ``/v1/jobs/{id}/plots``: a finished job's result to look at
(CSV and plots rendered server-side, in the render processes: :mod:`app.render_pool`), for the
job's owner only, like its result."""

from __future__ import annotations

import json
from typing import Any

from fastapi import APIRouter, Response
from starlette.concurrency import run_in_threadpool

from app import jobs_service
from app.deps import DatabaseDep, OwnerDep, ServiceDep
from app.errors import ApiError
from app.report import PLOT_FORMATS, available_plots, trajectory_csv
from app.report.plots import UnknownPlotError, render_stored_plot
from app.report.table import NoTrajectoryError
from app.views import ErrorResponse

router = APIRouter(prefix="/v1/jobs", tags=["results"])

_ERRORS: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorResponse, "description": "No such job of yours (or no such plot)."},
    409: {
        "model": ErrorResponse,
        "description": "Not finished yet, or finished without a result (or a trajectory).",
    },
}


def _result(database: Any, owner: str, job_id: str) -> dict[str, Any]:
    """The finished job's result document (the same 404 / 409 as ``/result``)."""
    document: dict[str, Any] = json.loads(jobs_service.get_result(database, owner, job_id))
    return document


@router.get(
    "/{job_id}/trajectory.csv",
    response_class=Response,
    responses={
        200: {
            "description": "One row per node; the header names each column and its unit.",
            "content": {"text/csv": {"schema": {"type": "string"}}},
        },
        **_ERRORS,
    },
    summary="The optimized trajectory as CSV",
)
def get_trajectory_csv(job_id: str, database: DatabaseDep, owner: OwnerDep) -> Response:
    """The result's trajectory as CSV, ``name [unit]`` headers, exact numbers."""
    result = _result(database, owner, job_id)
    try:
        text = trajectory_csv(result)
    except NoTrajectoryError as exc:
        raise ApiError(409, "no_trajectory", f"job {job_id}: {exc}") from exc
    return Response(
        text,
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="{job_id}-trajectory.csv"'},
    )


@router.get(
    "/{job_id}/plots",
    response_model=list[str],
    responses=_ERRORS,
    summary="The names of a result's plots",
)
def list_plots(job_id: str, database: DatabaseDep, owner: OwnerDep) -> list[str]:
    """Each plot the result has data for; fetch one as ``plots/{name}.png`` or ``.svg``."""
    return available_plots(_result(database, owner, job_id))


RENDER_ERRORS: dict[int | str, dict[str, Any]] = {
    429: {
        "model": ErrorResponse,
        "description": "Rate limit, or too many of this client's plots waiting to be rendered "
        "(`too_many_renders`); retry after Retry-After.",
    },
    503: {
        "model": ErrorResponse,
        "description": "The database is unreachable, or a render process is being restarted "
        "(`render_unavailable`); retry after Retry-After.",
    },
}
"""The refusals of a route that renders a plot."""


@router.get(
    "/{job_id}/plots/{name}.{fmt}",
    response_class=Response,
    responses={
        200: {
            "description": "The plot, rendered for this result.",
            "content": {media: {} for media in PLOT_FORMATS.values()},
        },
        **_ERRORS,
        **RENDER_ERRORS,
    },
    summary="Render one plot (PNG or SVG)",
)
async def get_plot(
    job_id: str, name: str, fmt: str, service: ServiceDep, owner: OwnerDep
) -> Response:
    """Plot ``name`` (one of ``/plots``) as ``fmt`` (png or svg): optimized nodes over the
    propagated flight, with the limits and the no-fly zones. Rendered once per API process, in
    a render process, one of the client's plots at a time."""
    media_type = plot_media_type(fmt)
    text = await run_in_threadpool(jobs_service.get_result, service.database, owner, job_id)
    try:
        image = await service.renders.render(
            owner, ("job", job_id, name, fmt), render_stored_plot, text, name, fmt
        )
    except UnknownPlotError as exc:
        raise ApiError(
            404,
            "plot_not_found",
            f"job {job_id} has no plot {name!r}; its plots: {', '.join(exc.available) or 'none'}",
            field="name",
        ) from None
    return Response(image, media_type=media_type)


def plot_media_type(fmt: str) -> str:
    """The media type of plot format ``fmt``; 404 ``plot_format_not_found`` for another."""
    if fmt not in PLOT_FORMATS:
        raise ApiError(
            404,
            "plot_format_not_found",
            f"no plot format {fmt!r}; formats: {', '.join(sorted(PLOT_FORMATS))}",
            field="fmt",
        )
    return PLOT_FORMATS[fmt]
