"""``/v1/scenarios`` and ``/v1/methods``: the built-in problems and the solution methods."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from app.errors import ApiError
from app.views import ErrorResponse, MethodView, ScenarioSummary, ScenarioView

router = APIRouter(prefix="/v1", tags=["catalog"])


@router.get("/scenarios", response_model=list[ScenarioSummary], summary="List scenarios")
def list_scenarios() -> list[ScenarioSummary]:
    """The built-in problems with their sources."""
    from worker.solver.scenarios import list_scenarios as _list

    return [ScenarioSummary(name=s.name, title=s.title, source=s.source) for s in _list()]


@router.get(
    "/scenarios/{name}",
    response_model=ScenarioView,
    responses={404: {"model": ErrorResponse}},
    summary="Show a scenario",
)
def get_scenario(name: str) -> ScenarioView:
    """One built-in problem: its document, source and the corrections made to the paper's data."""
    from worker.solver.scenarios import get_scenario as _get

    try:
        s = _get(name)
    except KeyError as exc:  # its message names the close matches ("did you mean ...?")
        raise ApiError(404, "scenario_not_found", str(exc)) from None
    return ScenarioView(
        name=s.name,
        title=s.title,
        source=s.source,
        corrections=list(s.corrections),
        problem=s.problem,
    )


@router.get("/methods", response_model=list[MethodView], summary="List methods")
def list_methods() -> list[dict[str, Any]]:
    """Each method with the features it supports and its default options."""
    from worker.solver.methods import list_methods as _list

    return list(_list())
