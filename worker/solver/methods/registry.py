"""The registry of solution methods, built from the one list of options models
(``app.schemas.methods.METHOD_OPTION_TYPES``): method ``a-b`` is the package
``worker.solver.methods.a_b``, whose ``METHOD`` describes it, checks support and runs it.

``check_support`` refuses, with a field path and a reason, any feature of a problem that the
chosen method cannot handle, so a request fails fast with 422 instead of deep in a worker.
"""

from __future__ import annotations

import importlib
from typing import Any

from app.schemas import FieldIssue, ProblemDocument
from app.schemas.methods import METHOD_OPTION_TYPES, method_name
from worker.solver.methods.base import MethodInfo, issue


def package_of(name: str) -> str:
    """The solver package of method ``name``."""
    return f"worker.solver.methods.{name.replace('-', '_')}"


def _load() -> dict[str, MethodInfo]:
    """Every method's ``MethodInfo``, checked against its options model."""
    found: dict[str, MethodInfo] = {}
    for options_type in METHOD_OPTION_TYPES:
        name = method_name(options_type)
        info = importlib.import_module(package_of(name)).METHOD
        if not isinstance(info, MethodInfo) or info.name != name:
            raise RuntimeError(f"{package_of(name)}.METHOD does not describe method {name!r}")
        if info.options_type is not options_type:
            raise RuntimeError(f"{name}: its package and its options model disagree")
        found[name] = info
    return found


METHODS: dict[str, MethodInfo] = _load()
"""Every method by name, in the order of the options list."""


def list_methods() -> list[dict[str, Any]]:
    """Every method, JSON-ready, with its features and default options."""
    return [info.describe() for info in METHODS.values()]


def check_support(doc: ProblemDocument) -> list[FieldIssue]:
    """Issues that make ``doc`` unsolvable by its method (empty when it is fine)."""
    info = METHODS.get(doc.method.name)
    if info is None:
        return [issue("method.name", f"unknown method {doc.method.name!r}", "unknown_method")]
    out = list(info.check(doc))
    if doc.initial_guess is not None and doc.initial_guess.trajectory is None:
        out.append(
            issue(
                "initial_guess.from_job",
                "only the service resolves from_job (it copies that job's trajectory); "
                "here give initial_guess.trajectory",
            )
        )
    return out
