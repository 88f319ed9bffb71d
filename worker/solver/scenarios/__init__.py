"""Built-in scenarios: the papers' test cases as problem documents, with their sources."""

from __future__ import annotations

import difflib
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


SHOWN_NAME_CHARS = 60
"""Longest part of an unknown name repeated in a message."""


def shown_name(name: str) -> str:
    """``name`` as a message repeats it: cut to ``SHOWN_NAME_CHARS`` characters."""
    return name if len(name) <= SHOWN_NAME_CHARS else name[: SHOWN_NAME_CHARS - 3] + "..."


class UnknownScenarioError(KeyError):
    """No built-in scenario has the name asked for; carries the close matches and all names.

    A ``KeyError`` for the callers that catch one; unlike a plain ``KeyError`` its ``str()`` is
    the message itself, without quotes.
    """

    def __init__(self, name: str, known: list[str]) -> None:
        self.name = name
        self.known = known
        self.suggestions = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
        if self.suggestions:
            hint = "did you mean " + " or ".join(repr(s) for s in self.suggestions) + "?"
        else:
            hint = "known scenarios: " + (", ".join(known) or "none")
        super().__init__(f"unknown scenario {shown_name(name)!r}; {hint}")

    def __str__(self) -> str:
        """The message, unquoted (``KeyError`` would show its repr)."""
        return str(self.args[0])


def get_scenario(name: str) -> Scenario:
    """The scenario called ``name``; :class:`UnknownScenarioError` (a ``KeyError``) if none."""
    scenarios = _load_all()
    if name not in scenarios:
        raise UnknownScenarioError(name, sorted(scenarios))
    return scenarios[name]
