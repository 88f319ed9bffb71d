"""A method refuses, naming the field, the problem features it cannot handle."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from app.schemas import ProblemDocument
from worker.solver.methods import check_support, list_methods
from worker.solver.scenarios import get_scenario, list_scenarios


def _raw() -> dict[str, Any]:
    return json.loads(json.dumps(get_scenario("rlv-min-heat-load").problem))


def _issues(raw: dict[str, Any]) -> dict[str, str]:
    return {i.field: i.message for i in check_support(ProblemDocument.model_validate(raw))}


def test_scenario_is_supported() -> None:
    assert _issues(_raw()) == {}


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        (
            lambda r: r.update(final_time={"kind": "fixed", "value_s": 1600}),
            "final_time",
            "final time",
        ),
        (
            lambda r: r.update(
                no_fly_zones=[
                    {"center_latitude_deg": 40, "center_longitude_deg": 40, "radius_km": 100}
                ]
            ),
            "no_fly_zones",
            "no-fly",
        ),
        (
            lambda r: r["control_limits"].update(bank_rate_max_deg_s=5),
            "control_limits.bank_rate_max_deg_s",
            "rate",
        ),
        (
            lambda r: r["control_limits"].update(bank_min_deg=-60),
            "control_limits.bank_min_deg",
            "asymmetric bank range",
        ),
        (
            lambda r: r.update(objective="max_terminal_velocity"),
            "objective.terms[0].name",
            "cannot minimize",
        ),
        (lambda r: r["energy"].update(initial=0.6), "energy.initial", "disagrees"),
        (lambda r: r["terminal"].update(velocity_m_s=900), "terminal.velocity_m_s", "follows from"),
        (lambda r: r.pop("energy"), "energy.final", "final energy"),
        (
            lambda r: r["vehicle"].update(
                angle_of_attack={"mode": "optimized", "min_deg": 0, "max_deg": 40}
            ),
            "vehicle.angle_of_attack",
            "scheduled",
        ),
    ],
)
def test_unsupported_features_are_refused(change: Any, field: str, words: str) -> None:
    raw = _raw()
    change(raw)
    issues = _issues(raw)
    assert field in issues, issues
    assert words in issues[field]


def test_methods_and_scenarios_are_listed() -> None:
    methods = {m["name"]: m for m in list_methods()}
    assert methods["energy-scp"]["default_options"]["nodes"] == 121
    assert "min_heat_load" in methods["energy-scp"]["objectives"]
    for scenario in list_scenarios():
        ProblemDocument.model_validate(scenario.problem)
        assert scenario.source and scenario.corrections


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "app.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def test_cli_rejects_an_invalid_file_with_the_field_named(tmp_path: Path) -> None:
    raw = _raw()
    raw["vehicle"]["mass_kg"] = -5
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(raw))
    done = _cli("solve", str(path))
    assert done.returncode == 2
    assert "vehicle.mass_kg" in done.stderr


def test_cli_solves_a_scenario_and_writes_the_result(tmp_path: Path) -> None:
    out = tmp_path / "result.json"
    done = _cli("solve", "rlv-min-heat-load", "--nodes", "61", "-o", str(out))
    result = json.loads(out.read_text())
    assert result["trajectory"]["nodes"] == 61
    assert "iter   1" in done.stderr  # per-iteration progress on stderr
    assert done.returncode == (0 if result["status"] == "succeeded" else 1)
    assert f"status: {result['status']}" in done.stdout


def test_kernels_are_loaded_before_the_clock_only_for_methods_that_run_them(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``solve_problem`` loads the compiled kernels before it starts the optimization's clock
    (so ``timing.wall_s`` is the optimization's own) for a method that declares
    ``warm_kernels`` (both do) when the problem's models have compiled forms, and not when they
    have none."""
    from worker.solver import api

    calls: list[str] = []

    def warm_up(notice: Any = None) -> float:
        calls.append("warm")
        return 0.0

    monkeypatch.setattr(api, "warm_up", warm_up)
    for name in ("rlv-max-terminal-velocity", "rlv-min-heat-load"):
        raw = dict(get_scenario(name).problem)
        raw["method"] = {**raw["method"], "max_iterations": 1}
        calls.clear()
        api.solve_problem(ProblemDocument.model_validate(raw))
        assert calls == ["warm"], name
    # a problem whose force models have no compiled form runs no kernel: nothing to load
    monkeypatch.setattr(api, "compiled_parameters", lambda forces, omega: None)
    calls.clear()
    api.solve_problem(ProblemDocument.model_validate(raw))
    assert calls == []
