"""``/v1/jobs/{id}/trajectory.csv`` and ``/v1/jobs/{id}/plots``: a finished job's result to look at
(CSV and plots rendered server-side), for the job's owner only, like its result."""

from __future__ import annotations

import json
from typing import Any

from fastapi import APIRouter, Response

from app import jobs_service
from app.deps import DatabaseDep, OwnerDep
from app.errors import ApiError
from app.report import PLOT_FORMATS, available_plots, render_plot, trajectory_csv
from app.report.cache import RenderCache
from app.report.table import NoTrajectoryError
from app.views import ErrorResponse

router = APIRouter(prefix="/v1/jobs", tags=["results"])

PLOTS = RenderCache()
"""This process's rendered plots of finished jobs (a finished result never changes)."""

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


@router.get(
    "/{job_id}/plots/{name}.{fmt}",
    response_class=Response,
    responses={
        200: {
            "description": "The plot, rendered for this result.",
            "content": {media: {} for media in PLOT_FORMATS.values()},
        },
        **_ERRORS,
    },
    summary="Render one plot (PNG or SVG)",
)
def get_plot(job_id: str, name: str, fmt: str, database: DatabaseDep, owner: OwnerDep) -> Response:
    """Plot ``name`` (one of ``/plots``) as ``fmt`` (png or svg): optimized nodes over the
    propagated flight, with the limits and no-fly zones."""
    media_type = plot_media_type(fmt)
    result = _result(database, owner, job_id)
    names = available_plots(result)
    if name not in names:
        raise ApiError(
            404,
            "plot_not_found",
            f"job {job_id} has no plot {name!r}; its plots: {', '.join(names) or 'none'}",
            field="name",
        )
    image = PLOTS.get((job_id, name, fmt), lambda: render_plot(result, name, fmt))
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
