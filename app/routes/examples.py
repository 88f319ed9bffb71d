"""Request-body examples shown in the OpenAPI document."""

from __future__ import annotations

from typing import Any

from app.schemas import RLV_MIN_HEAT_LOAD

PROBLEM_EXAMPLES: dict[str, dict[str, Any]] = {
    "scenario": {
        "summary": "A built-in scenario, made small",
        "description": "The scenario's problem with fewer nodes and iterations merged in.",
        "value": {
            "scenario": "rlv-min-heat-load",
            "overrides": {"method": {"nodes": 20, "max_iterations": 10}},
        },
    },
    "scenario_method": {
        "summary": "A built-in scenario with method options",
        "value": {"scenario": "rlv-min-heat-load", "method": {"nodes": 60, "time_limit_s": 60}},
    },
    "document": {
        "summary": "A full problem document",
        "value": RLV_MIN_HEAT_LOAD,
    },
}

VALIDATE_EXAMPLES: dict[str, dict[str, Any]] = {
    "document": PROBLEM_EXAMPLES["document"],
    "invalid": {
        "summary": "A document with several errors (all are reported)",
        "value": {
            **RLV_MIN_HEAT_LOAD,
            "vehicle": {**RLV_MIN_HEAT_LOAD["vehicle"], "mass_kg": -1},
            "method": {"name": "energy-scp", "nodes": 1},
            "unknown_field": True,
        },
    },
}
