"""``auto``'s rule: the methods that accept a document, in the order they are tried, and why.

The rule has two steps. A method accepts a document when its own support check (the
registry's: capability flags for phases and propulsion, then the method's ``check_support``,
which names every feature it cannot handle) finds nothing, run on the document with that
method's options as auto would try it. The methods that accept are tried in the one order of
:data:`PREFERENCE`; each entry says why it stands where it does. Because each method refuses
what it cannot fly, this order yields the feature rules: phases or propulsion -> lgl-sqp; a
fixed final time -> foh-ptr, then cheb-scvx; a free final time beyond energy-scp's class ->
foh-ptr, then cheb-scvx; zones -> foh-ptr or cheb-scvx, then hp-scp; an optimized angle of
attack -> foh-ptr, cheb-scvx, hp-scp, lgl-sqp; a parabolic polar -> foh-ptr (on the sphere),
cheb-scvx; waypoints -> cheb-scvx; energy-scp on its own class (free final time, a scheduled
angle of attack, no zones, waypoints or rate limits).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

from pydantic import ValidationError

from app.schemas import FieldIssue, ProblemDocument, issues_from_validation_error
from app.schemas.methods import METHOD_OPTIONS, AutoOptions, ScpRunOptions
from worker.solver.methods import registry


class Preference(NamedTuple):
    """A method's place in auto's order and the reason for it."""

    name: str
    reason: str


PREFERENCE: tuple[Preference, ...] = (
    Preference(
        "energy-scp",
        "first where it applies (free final time, a scheduled angle of attack, no zones, "
        "waypoints or rate limits): the fastest on that class, under a second at its default "
        "121 nodes, and every variant of its paper's case meets the acceptance",
    ),
    Preference(
        "foh-ptr",
        "a fixed final time (paper 002's grid spans it) or a free one (its interval lengths "
        "as time dilations); zones, a bank-rate limit and an asymmetric bank range; an "
        "optimized angle of attack (with its rate limit) or a parabolic polar's normalized "
        "lift as a second held state; about a second on its paper's cases, a few seconds on a "
        "free final time",
    ),
    Preference(
        "cheb-scvx",
        "the widest reach (free or fixed final time, zones, waypoints, a bank-rate limit, any "
        "angle-of-attack law as a lift share, parabolic polars, the flat planet); seconds to "
        "tens of seconds",
    ),
    Preference(
        "hp-scp",
        "an optimized angle of attack as a state with rate limits on it, and min_control_effort; "
        "experimental and slower (tens of seconds)",
    ),
    Preference(
        "lgl-sqp",
        "the one method for phases and propulsion: a global search, then SQP; the slowest",
    ),
)
"""Every method, in the order auto tries those that accept a document."""


def _auto_defaults(name: str, doc: ProblemDocument) -> dict[str, Any] | None:
    """Auto's options of method ``name`` for ``doc``: the resolution of the problem's class, as
    the method's own defaults read it (``ProblemDocument.class_resolution``: auto hands every
    method explicit options, so the class is read here too); None for the rest, and for
    cheb-scvx when auto's own nodes are given (they run on the paper's intervals)."""
    if name == "cheb-scvx" and isinstance(doc.method, AutoOptions) and doc.method.nodes is not None:
        return None
    return doc.class_resolution(name) or None


@dataclass(frozen=True)
class Candidate:
    """A method that accepts the document: its options as auto tries it and why it is here."""

    name: str
    options: ScpRunOptions
    reason: str


@dataclass(frozen=True)
class Selection:
    """The methods that accept a document, in auto's order, and each refusal's reasons."""

    candidates: tuple[Candidate, ...]
    refused: dict[str, list[FieldIssue]]

    def describe(self) -> dict[str, Any]:
        """JSON-ready: the candidates in order, and per refusing method its reasons."""
        return {
            "candidates": [c.name for c in self.candidates],
            "refused": {
                name: [f"{i.field}: {i.message}" if i.field else i.message for i in issues]
                for name, issues in self.refused.items()
            },
        }


def with_method(doc: ProblemDocument, options: ScpRunOptions) -> ProblemDocument:
    """``doc`` with ``options`` as its method, validated again (some checks read the method's
    options, e.g. a constant reference bank within the bank range)."""
    document = doc.model_dump(mode="json")
    document["method"] = options.model_dump(mode="json")
    return ProblemDocument.model_validate(document)


def _prefixed(exc: ValidationError, prefix: str) -> list[FieldIssue]:
    """The issues of ``exc`` with ``prefix`` before each field path."""
    return [
        FieldIssue(
            field=f"{prefix}.{i.field}" if i.field else prefix, message=i.message, code=i.code
        )
        for i in issues_from_validation_error(exc)
    ]


def select(doc: ProblemDocument) -> Selection:
    """The methods that accept ``doc`` (whose method is auto), in auto's order."""
    auto = doc.method
    assert isinstance(auto, AutoOptions), auto
    candidates: list[Candidate] = []
    refused: dict[str, list[FieldIssue]] = {}
    for name, reason in PREFERENCE:
        defaults = _auto_defaults(name, doc)
        try:
            options = auto.options_for(name, defaults)
            unfit: list[FieldIssue] = []
        except ValidationError as exc:  # e.g. auto's nodes too few for it: what else it refuses
            options = METHOD_OPTIONS[name].model_validate({"name": name})
            unfit = _prefixed(exc, "method")
        try:
            issues = unfit + registry.check_support(with_method(doc, options))
        except ValidationError as exc:
            issues = unfit + issues_from_validation_error(exc)
        if issues:
            refused[name] = issues
        else:
            candidates.append(Candidate(name, options, reason))
    return Selection(tuple(candidates), refused)


def refusal_issues(selection: Selection) -> list[FieldIssue]:
    """The 422 issues of a document no method accepts: a summary, then each method's reasons
    (each issue at its own field, its message led by the method's name)."""
    summary = "; ".join(
        f"{name} refuses {', '.join(dict.fromkeys(i.field or '(document)' for i in issues))}"
        for name, issues in selection.refused.items()
    )
    lead = FieldIssue(
        field="method",
        message=f"no method accepts this problem, so auto has none to try: {summary}",
        code="no_method_accepts",
    )
    return [lead] + [
        FieldIssue(field=i.field, message=_led_by(name, i.message), code=i.code)
        for name, issues in selection.refused.items()
        for i in issues
    ]


def _led_by(name: str, message: str) -> str:
    """``message`` led by the method's name (most of the methods' own messages already are)."""
    return message if message.split(" ", 1)[0].rstrip(":") == name else f"{name}: {message}"


def check_support(doc: ProblemDocument) -> list[FieldIssue]:
    """Issues that make ``doc`` unsolvable by its method (empty when it is fine); for auto, by
    every method."""
    if not isinstance(doc.method, AutoOptions):
        return registry.check_support(doc)
    selection = select(doc)
    return [] if selection.candidates else refusal_issues(selection)
