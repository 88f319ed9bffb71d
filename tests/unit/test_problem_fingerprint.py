"""The problem's fingerprint and the software a result names (``app.schemas.fingerprint``,
``worker.solver.software``): a user recomputes the fingerprint from the document as solved; a
result names every library whose version can change it; nothing of it fails a solve."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from app.schemas import ProblemDocument
from app.schemas.fingerprint import problem_sha256
from worker.solver import software
from worker.solver.result import input_provenance
from worker.solver.scenarios import get_scenario, list_scenarios


@pytest.mark.parametrize("scenario", [s.name for s in list_scenarios()])
def test_the_stored_document_hashes_as_the_solver_hashes_it(scenario: str) -> None:
    problem = ProblemDocument.model_validate(get_scenario(scenario).problem)
    stored = json.loads(json.dumps(problem.model_dump(mode="json")))  # what the service keeps
    again = ProblemDocument.model_validate(stored)  # what a worker solves from it
    text = json.dumps(stored, sort_keys=True, separators=(",", ":"))
    assert problem_sha256(again) == hashlib.sha256(text.encode()).hexdigest()


def test_a_changed_default_changes_the_fingerprint() -> None:
    base = get_scenario("rlv-min-heat-load").problem
    one = ProblemDocument.model_validate(base)
    other = ProblemDocument.model_validate({**base, "method": {**base["method"], "nodes": 120}})
    assert problem_sha256(one) != problem_sha256(other)


def test_the_provenance_names_its_input_and_software() -> None:
    scenario = get_scenario("rlv-min-heat-load").problem
    problem = ProblemDocument.model_validate(scenario)
    found = input_provenance(problem)
    assert found["problem_sha256"] == problem_sha256(problem)
    assert "source_job" not in found
    for name in ("numpy", "scipy", "clarabel", "piqp", "cvxpy", "numba", "llvmlite", "ussa1976",
                 "pymoo"):  # fmt: skip
        assert found["packages"][name], name
    assert found["software"]["name"] == "entry-trajopt" and found["software"]["version"]
    trajectory = {
        "time_s": [0, 1500],
        "altitude_m": [105000, 30000],
        "longitude_deg": [0, 15],
        "latitude_deg": [0, 70],
        "velocity_m_s": [7449.81, 1000],
        "flight_path_angle_deg": [-0.5, -10],
        "heading_deg": [0, 15],
        "bank_deg": [40, 40],
    }
    guess = {"from_job": "3f2b8c1e-6d0a-4c55-9d1e-2a7f3b9c4e10", "trajectory": trajectory}
    warm = ProblemDocument.model_validate({**scenario, "initial_guess": guess})
    assert input_provenance(warm)["source_job"] == guess["from_job"]


def test_the_revision_is_none_outside_a_checkout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    software.source_revision.cache_clear()
    monkeypatch.setattr(software, "_CHECKOUT", tmp_path)
    try:
        assert software.source_revision() is None
        (tmp_path / ".git").write_text("gitdir: /nonexistent\n")  # a broken checkout
        software.source_revision.cache_clear()
        assert software.source_revision() is None
    finally:
        software.source_revision.cache_clear()


def test_the_versions_are_read_once() -> None:
    assert software.library_versions() == software.library_versions()
    assert software._library_versions.cache_info().currsize == 1
