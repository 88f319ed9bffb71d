"""Server caps (pure logic): what they refuse and how the refusal reads."""

from __future__ import annotations

import copy
from typing import Any

from app.caps import cap_issues
from app.schemas import METHOD_NAMES, ProblemDocument
from app.settings import Settings
from worker.solver.scenarios import get_scenario, list_scenarios

SKIP = "shuttle-skip-min-propellant"


def _doc(name: str, **method: Any) -> ProblemDocument:
    document: dict[str, Any] = copy.deepcopy(get_scenario(name).problem)
    document["method"] = {"name": document["method"]["name"], **method}
    return ProblemDocument.model_validate(document)


def test_the_default_caps_admit_every_methods_defaults_and_every_scenario() -> None:
    settings = Settings()
    for scenario in list_scenarios():
        doc = ProblemDocument.model_validate(scenario.problem)
        assert cap_issues(doc, settings) == [], scenario.name
    for method in METHOD_NAMES:
        scenario = next(s for s in list_scenarios() if s.problem["method"]["name"] == method)
        assert cap_issues(_doc(scenario.name), settings) == [], method


def test_a_methods_default_over_an_operators_cap_says_it_is_the_default() -> None:
    """A default the user never wrote is named as the method's default, with what to give."""
    settings = Settings(max_iterations=500)
    (issue,) = cap_issues(_doc(SKIP), settings)
    assert issue.field == "method.max_iterations"
    assert issue.message == (
        "the method's default 600 exceeds the server cap TRAJOPT_MAX_ITERATIONS=500; give "
        "method.max_iterations at most 500"
    )
    (given,) = cap_issues(_doc(SKIP, max_iterations=700), settings)
    assert given.message == "700 exceeds the server cap TRAJOPT_MAX_ITERATIONS=500"


def test_each_phases_node_count_is_capped() -> None:
    settings = Settings(max_nodes=100)
    issues = cap_issues(_doc(SKIP, phase_nodes=[81, 121]), settings)
    assert [(i.field, i.message) for i in issues] == [
        ("method.phase_nodes.1", "121 exceeds the server cap TRAJOPT_MAX_NODES=100")
    ]
