"""The registry of solution methods, built from the one list of options models
(``app.schemas.methods.METHOD_OPTION_TYPES``): method ``a-b`` is the package
``worker.solver.methods.a_b``, whose ``METHOD`` describes it, checks support and runs it.

``check_support`` refuses, with a field path and a reason, any feature of a problem that the
chosen method cannot handle, so a request fails fast with 422 instead of deep in a worker.
Phases and propulsion are refused here, from the method's capability flags, before the
method's own checks (which assume a single-phase problem without propulsion).
"""

from __future__ import annotations

import importlib

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


_CAPABILITIES = (("phases", "phases"), ("vehicle.propulsion", "propulsion"))
"""Each feature a method must declare: its field path and its ``MethodInfo`` flag."""


def _scope(info: MethodInfo) -> str:
    """What the method solves, as far as phases and propulsion go."""
    phases = "phased or single-phase problems" if info.phases else "single-phase problems"
    return f"{phases} {'with or without' if info.propulsion else 'without'} propulsion"


def capability_issues(doc: ProblemDocument, info: MethodInfo) -> list[FieldIssue]:
    """Phases and propulsion in ``doc`` that the method ``info`` does not handle."""
    used = {"phases": bool(doc.phases), "propulsion": doc.vehicle.propulsion is not None}
    out = []
    for field, flag in _CAPABILITIES:
        if not used[flag] or getattr(info, flag):
            continue
        able = [name for name, other in METHODS.items() if getattr(other, flag)]
        which = f"{', '.join(able)}; " if able else ""
        out.append(
            issue(
                field,
                f"{info.name} solves {_scope(info)}; choose a method that handles {flag} "
                f"({which}see GET /v1/methods)",
            )
        )
    return out


def check_support(doc: ProblemDocument) -> list[FieldIssue]:
    """Issues that make ``doc`` unsolvable by its method (empty when it is fine)."""
    info = METHODS.get(doc.method.name)
    if info is None:
        return [issue("method.name", f"unknown method {doc.method.name!r}", "unknown_method")]
    refused = capability_issues(doc, info)
    if refused:  # the method's own checks would misread what it cannot fly
        return refused
    out = list(info.check(doc))
    guess = doc.initial_guess
    if guess is not None and guess.kind == "global":
        out += global_start_issues(doc)
    elif guess is not None and guess.trajectory is None:
        out.append(
            issue(
                "initial_guess.from_job",
                "only the service resolves from_job (it copies that job's trajectory); "
                "here give initial_guess.trajectory",
            )
        )
    return out


def global_start_issues(doc: ProblemDocument) -> list[FieldIssue]:
    """What a global start (``phase_search``: the spherical point-mass model, an angle of attack
    searched or scheduled) cannot fly yet."""
    out: list[FieldIssue] = []
    if doc.vehicle.aerodynamics.model == "parabolic_polar":
        out.append(
            issue(
                "initial_guess.kind",
                "a global start searches an angle of attack or flies its schedule; not yet a "
                "parabolic polar's lift coefficient",
            )
        )
    if doc.planet.model == "flat":
        out.append(
            issue(
                "initial_guess.kind", "a global start flies the spherical model, not the flat one"
            )
        )
    return out
