"""A user's free-final-time problem, no method named, through the ``trajopt`` command.

docs/examples/user-free-time-min-heat.json: paper 000's RLV (vehicle, planet, limits) from a
moved entry point to 30 deg E, 55 deg N at 25 km, minimum heat load, free final time, no zone and
no method, so auto runs. It must succeed (converged and verified) with a heat load within 0.5 %
of the independent NLP reference stored in ``data/free-time-min-heat-reference.json`` (with its
provenance: Hermite-Simpson collocation and IPOPT, two meshes agreeing, several starts, the
bank re-flown). 0.5 % is the acceptance bar of the problem; the verified flight's own heat load
is held to the same bar.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.integration.harness import run_cli, service_free_env

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "docs" / "examples" / "user-free-time-min-heat.json"
REFERENCE = json.loads(
    (Path(__file__).with_name("data") / "free-time-min-heat-reference.json").read_text()
)
TOLERANCE = 0.005
"""Relative heat-load error allowed: the problem's acceptance bar (0.5 %)."""


def test_auto_solves_the_users_free_time_problem_within_the_bar(tmp_path: Path) -> None:
    env = service_free_env(TRAJOPT_DATA_DIR=str(tmp_path / "data"))
    out = tmp_path / "result.json"
    done = run_cli("solve", str(EXAMPLE), "-q", "-o", str(out), env=env, cwd=tmp_path, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    result = json.loads(out.read_text())
    assert result["status"] == "succeeded"
    assert result["provenance"]["selection"]["chosen"] == result["method"]  # auto chose it
    assert result["verification"]["feasible"]
    reference = REFERENCE["reference"]["objective"]
    heat = result["objective"]["value"]
    flown = result["verification"]["heat_load_J_m2"]
    assert abs(heat / reference - 1.0) <= TOLERANCE, (heat, reference)
    assert abs(flown / reference - 1.0) <= TOLERANCE, (flown, reference)
