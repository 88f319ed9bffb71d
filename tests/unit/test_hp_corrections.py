"""hp-scp's second-order corrections step onto the constraints without the objective's pull.

The user-problem suite's 082 (Shuttle, maximum final latitude, active path limits): with the
objective in the corrections each of them was another step along it, the defects a step left
stood at about 0.07 (scaled sum), the ratio test sat at 0.22-0.6 and the run crept to its
reference's value in 333 iterations (measured before the change; docs/methods/hp-scp.md).
Without it the corrections remove those defects and the trust weight lightens: 27 iterations.
"""

from __future__ import annotations

import json
from pathlib import Path

from app.schemas import ProblemDocument
from worker.solver.api import solve_problem

SUITE = Path(__file__).resolve().parents[2] / "bench" / "user_problems" / "data"
BUDGET = 60
"""Twice the iterations measured with the change, a fifth of those measured before it."""


def test_a_maximum_final_latitude_converges_without_a_linear_tail() -> None:
    (path,) = SUITE.glob("082-*.json")
    record = json.loads(path.read_text())
    document = {**record["problem"], "method": {"name": "hp-scp", "max_iterations": BUDGET}}
    result = solve_problem(ProblemDocument.model_validate(document))
    assert result["status"] == "succeeded", result.get("failure")
    # the suite's success bar: within 0.5 % of the NLP reference's final latitude
    reference = record["objective"]["value"]
    assert abs(result["objective"]["value"] - reference) <= 0.005 * reference
    ratios = [r["extra"]["ratio"] for r in result["history"][-5:] if "ratio" in r["extra"]]
    assert ratios and max(ratios) > 0.75  # a model the steps trust again at the end
