"""Built-in scenarios: the papers' test cases as problem documents, with their sources."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import Any


@dataclass(frozen=True)
class Scenario:
    """A named built-in problem: the document plus where it comes from and what was corrected."""

    name: str
    title: str
    source: str
    corrections: list[str] = field(default_factory=list)
    problem: dict[str, Any] = field(default_factory=dict)


@cache
def _load_all() -> dict[str, Scenario]:
    found: dict[str, Scenario] = {}
    for entry in sorted(resources.files(__package__).iterdir(), key=lambda p: p.name):
        if not entry.name.endswith(".json"):
            continue
        raw = json.loads(entry.read_text(encoding="utf-8"))
        scenario = Scenario(
            name=raw["name"],
            title=raw["title"],
            source=raw["source"],
            corrections=list(raw.get("corrections", [])),
            problem=raw["problem"],
        )
        found[scenario.name] = scenario
    return found


def list_scenarios() -> list[Scenario]:
    """All built-in scenarios, sorted by name."""
    return [s for _, s in sorted(_load_all().items())]


def get_scenario(name: str) -> Scenario:
    """The scenario called ``name``; ``KeyError`` naming the known ones if there is none."""
    scenarios = _load_all()
    if name not in scenarios:
        known = ", ".join(sorted(scenarios)) or "none"
        raise KeyError(f"unknown scenario {name!r}; known scenarios: {known}")
    return scenarios[name]
