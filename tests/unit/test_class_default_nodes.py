"""foh-ptr's nodes and cheb-scvx's nodes and intervals, when a document gives none, follow the
problem's class, named or through auto; a document's own always win and a stored document keeps
what was solved."""

from __future__ import annotations

import copy
from typing import Any

import pytest

from app.schemas import ProblemDocument
from worker.solver.methods.selection import select
from worker.solver.scenarios import get_scenario


def _rlv(**changes: Any) -> dict[str, Any]:
    """The built-in RLV maximum terminal speed (fixed final time, the bank alone) with changes."""
    document = copy.deepcopy(get_scenario("rlv-max-terminal-velocity").problem)
    document["method"] = {"name": "foh-ptr"}
    document.update(changes)
    return document


FREE = {"kind": "free", "max_s": 3000}


@pytest.mark.parametrize(
    ("changes", "nodes"),
    [
        ({}, 40),
        ({"final_time": FREE}, 80),
        ({"final_time": FREE, "objective": "min_heat_load"}, 120),
        ({"objective": "min_heat_load"}, 40),
    ],
)
def test_nodes_follow_the_class(changes: dict[str, Any], nodes: int) -> None:
    doc = ProblemDocument.model_validate(_rlv(**changes))
    assert doc.method.nodes == nodes
    # the stored document says what was solved, and reads back the same
    again = ProblemDocument.model_validate(doc.model_dump(mode="json"))
    assert again.method.nodes == nodes


def test_an_optimized_angle_of_attack_gets_finer_nodes() -> None:
    document = _rlv()
    document["vehicle"]["angle_of_attack"] = {"mode": "optimized", "min_deg": 5, "max_deg": 40}
    doc = ProblemDocument.model_validate(document)
    assert doc.method.nodes == 80


def test_the_documents_own_nodes_win() -> None:
    document = _rlv(final_time=FREE, objective="min_heat_load")
    document["method"]["nodes"] = 50
    assert ProblemDocument.model_validate(document).method.nodes == 50


def _candidates(document: dict[str, Any]) -> dict[str, Any]:
    selection = select(ProblemDocument.model_validate(document))
    return {c.name: c.options for c in selection.candidates}


def test_auto_gives_the_methods_the_same_nodes() -> None:
    document = _rlv(final_time=FREE, objective="min_heat_load")
    document["method"] = {"name": "auto"}
    candidates = _candidates(document)
    assert candidates["foh-ptr"].nodes == 120
    assert (candidates["cheb-scvx"].nodes, candidates["cheb-scvx"].intervals) == (401, 40)


def test_autos_own_nodes_reach_cheb_scvx_on_the_papers_intervals() -> None:
    document = _rlv(final_time=FREE, objective="min_heat_load")
    document["method"] = {"name": "auto", "nodes": 61}
    options = _candidates(document)["cheb-scvx"]
    assert (options.nodes, options.intervals) == (61, 20)


@pytest.mark.parametrize(
    ("changes", "resolution"),
    [
        ({"final_time": FREE}, (201, 20)),
        ({"final_time": FREE, "objective": "min_heat_load"}, (401, 40)),
    ],
)
def test_cheb_scvx_resolution_follows_the_class(
    changes: dict[str, Any], resolution: tuple[int, int]
) -> None:
    document = _rlv(**changes)
    document["method"] = {"name": "cheb-scvx"}
    doc = ProblemDocument.model_validate(document)
    assert (doc.method.nodes, doc.method.intervals) == resolution
    again = ProblemDocument.model_validate(doc.model_dump(mode="json"))
    assert (again.method.nodes, again.method.intervals) == resolution


def test_cheb_scvx_keeps_the_documents_nodes_on_the_papers_intervals() -> None:
    document = _rlv(final_time=FREE, objective="min_heat_load")
    document["method"] = {"name": "cheb-scvx", "nodes": 101}
    doc = ProblemDocument.model_validate(document)
    assert (doc.method.nodes, doc.method.intervals) == (101, 20)
