"""Turn a submitted body into a validated problem: a problem document, or a scenario + overrides.

Overrides are a JSON Merge Patch (RFC 7396) of the scenario's problem, with one addition: an
override object that changes the tag of a discriminated union (``planet.atmosphere.model``,
``method.name``, ...) replaces the scenario's object instead of merging into it, so a model
can be switched without deleting the old model's fields one by one. All problems are collected
and reported together (422) with dotted field paths.
"""

from __future__ import annotations

import copy
import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cache
from types import UnionType
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel, Field, TypeAdapter, ValidationError
from pydantic.fields import FieldInfo

from app.errors import MAX_ISSUES, ApiError, issues_message
from app.schemas import FieldIssue, ProblemDocument, issues_from_validation_error
from app.schemas.plausibility import PlausibilityWarning, plausibility_warnings
from app.views import ScenarioJobRequest


@dataclass(frozen=True)
class Submission:
    """A validated problem ready to store; a scenario's with the patches it was made with."""

    problem: ProblemDocument
    document: dict[str, Any]
    scenario: str | None
    patches: dict[str, Any] | None = None
    """A scenario request's ``{"overrides": ..., "method": ...}`` as submitted."""

    @property
    def method(self) -> str:
        """Name of the selected solution method."""
        return str(self.problem.method.name)

    def warnings(self) -> list[PlausibilityWarning]:
        """The problem's plausibility warnings (legal values far outside what vehicles fly)."""
        return plausibility_warnings(self.problem)

    def stored_warnings(self) -> list[dict[str, Any]]:
        """:meth:`warnings` as stored with the job."""
        return [w.model_dump(mode="json") for w in self.warnings()]


JsonPath = tuple[str, ...]
"""Member names from the document root; ``"[]"`` stands for any array item, ``"*"`` any key."""


@dataclass(frozen=True)
class TaggedUnion:
    """A discriminated union of the contract: where it sits, the key that picks the variant."""

    path: JsonPath
    key: str
    tags: tuple[str, ...]
    adapter: TypeAdapter[Any] = field(compare=False, repr=False)

    @property
    def location(self) -> str:
        """The union's place as a dotted path (``planet.atmosphere``, ``no_fly_zones[]``)."""
        return ".".join(self.path).replace(".[]", "[]")

    def matches(self, path: JsonPath) -> bool:
        """Whether ``path`` (a concrete member path) is where this union sits."""
        return len(path) == len(self.path) and all(
            mine in (theirs, "*") for mine, theirs in zip(self.path, path, strict=True)
        )

    def tag_of(self, value: dict[str, Any]) -> Any:
        """The variant ``value`` selects: its tag, else the one validation fills in, else None."""
        if self.key in value:
            return value[self.key]
        try:
            return getattr(self.adapter.validate_python(value), self.key, None)
        except ValidationError:
            return None

    def switches(self, target: dict[str, Any], patch: dict[str, Any]) -> bool:
        """Whether ``patch`` names a variant other than the one ``target`` is."""
        if patch.get(self.key) is None:
            return False
        current = self.tag_of(target)
        return current is not None and patch[self.key] != current


def _literal_values(annotation: Any) -> tuple[str, ...]:
    """The string values of a ``Literal`` annotation (empty for anything else)."""
    if get_origin(annotation) is not Literal:
        return ()
    return tuple(str(value) for value in get_args(annotation))


def _collect(
    annotation: Any,
    path: JsonPath,
    found: list[TaggedUnion],
    stack: tuple[type[BaseModel], ...],
    discriminator: str | None = None,
    metadata: tuple[Any, ...] = (),
) -> None:
    """Append every discriminated union reachable from ``annotation`` at ``path`` to ``found``."""
    origin = get_origin(annotation)
    args = get_args(annotation)
    if origin is Annotated:
        extra = tuple(annotation.__metadata__)
        for item in extra:
            if isinstance(item, FieldInfo) and isinstance(item.discriminator, str):
                discriminator = item.discriminator
        _collect(args[0], path, found, stack, discriminator, (*metadata, *extra))
    elif origin is Union or origin is UnionType:
        members = [arg for arg in args if arg is not type(None)]
        if discriminator is not None:
            tags = tuple(
                tag
                for member in members
                if isinstance(member, type) and issubclass(member, BaseModel)
                for tag in _literal_values(member.model_fields[discriminator].annotation)
            )
            adapter: TypeAdapter[Any] = TypeAdapter(
                Annotated[annotation, Field(discriminator=discriminator), *metadata]
            )
            found.append(TaggedUnion(path, discriminator, tags, adapter))
        for member in members:
            _collect(member, path, found, stack)
    elif origin in (list, tuple, set, frozenset):
        for arg in args:
            if arg is not Ellipsis:
                _collect(arg, (*path, "[]"), found, stack)
    elif origin is dict and len(args) == 2:
        _collect(args[1], (*path, "*"), found, stack)
    elif isinstance(annotation, type) and issubclass(annotation, BaseModel):
        if annotation in stack:
            return
        for name, info in annotation.model_fields.items():
            _collect(
                info.annotation,
                (*path, info.alias or name),
                found,
                (*stack, annotation),
                info.discriminator if isinstance(info.discriminator, str) else None,
                tuple(info.metadata),
            )


def tagged_unions(model: type[BaseModel]) -> tuple[TaggedUnion, ...]:
    """Every discriminated union in ``model``, found from its pydantic fields, in field order."""
    found: list[TaggedUnion] = []
    _collect(model, (), found, ())
    return tuple(found)


@cache
def problem_unions() -> tuple[TaggedUnion, ...]:
    """The discriminated unions of the problem document (built once)."""
    return tagged_unions(ProblemDocument)


def merge_patch(
    target: Any,
    patch: Any,
    unions: Sequence[TaggedUnion] = (),
    path: JsonPath = (),
) -> Any:
    """``target`` changed by ``patch`` as JSON Merge Patch (RFC 7396), plus the variant rule.

    ``null`` removes a member (a no-op when it is absent), objects merge member by member,
    arrays and scalars replace. Variant rule: at the place of one of ``unions``, a patch object
    whose tag names another variant than the target's replaces the target instead of merging
    into it, so the old variant's fields do not linger. Neither argument is modified.
    """
    if not isinstance(patch, dict):
        return copy.deepcopy(patch)
    union = next((u for u in unions if u.matches(path)), None)
    if not isinstance(target, dict) or (union is not None and union.switches(target, patch)):
        result: dict[str, Any] = {}
    else:
        result = copy.deepcopy(target)
    for name, value in patch.items():
        if value is None:
            result.pop(name, None)
        else:
            result[name] = merge_patch(result.get(name), value, unions, (*path, name))
    return result


def apply_overrides(document: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """A problem document changed by an overrides document (``merge_patch`` on its unions)."""
    merged: dict[str, Any] = merge_patch(document, overrides, problem_unions())
    return merged


def request_fingerprint(body: Any) -> str:
    """SHA-256 of the body's canonical JSON (key order and spacing do not matter).

    A ``NaN`` or infinite number is hashed as its JSON token: the body is fingerprinted before
    it is validated, and validation refuses such a number naming its field.
    """
    canonical = json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(canonical.encode()).hexdigest()


def invalid(issues: list[FieldIssue], what: str = "problem", total: int | None = None) -> ApiError:
    """The 422 error listing the issues (the first ``MAX_ISSUES`` of ``total``, if given)."""
    total = len(issues) if total is None else total
    first = issues[0] if issues else None
    if first is None:
        message = f"the {what} has {total} error(s)"
    else:
        message = issues_message(f"the {what} has", total, first.field, first.message)
    return ApiError(
        422,
        f"invalid_{what}",
        message,
        field=first.field if first else None,
        issues=[i.model_dump() for i in issues[:MAX_ISSUES]],
        issues_total=total,
    )


def _validation_issues(exc: ValidationError, what: str = "problem") -> ApiError:
    """The 422 error of a pydantic ``ValidationError``, converting only the issues it lists."""
    listed = issues_from_validation_error(exc, limit=MAX_ISSUES)
    return invalid(listed, what, total=exc.error_count())


def _scenario_document(body: dict[str, Any]) -> tuple[dict[str, Any], str, dict[str, Any]]:
    from worker.solver.scenarios import get_scenario

    try:
        request = ScenarioJobRequest.model_validate(body)
    except ValidationError as exc:
        raise _validation_issues(exc, "request") from None
    try:
        scenario = get_scenario(request.scenario)
    except KeyError as exc:
        issue = FieldIssue(field="scenario", message=str(exc.args[0]), code="unknown_scenario")
        raise invalid([issue], "request") from None
    document = apply_overrides(scenario.problem, request.overrides)
    if request.method is not None:
        document = apply_overrides(document, {"method": request.method})
    return document, scenario.name, {"overrides": request.overrides, "method": request.method}


def resolve_submission(body: Any) -> Submission:
    """Validate ``body`` (problem document or scenario request); raises a 422 ``ApiError``."""
    if not isinstance(body, dict):
        issue = FieldIssue(field="", message="the body must be a JSON object", code="dict_type")
        raise invalid([issue], "request")
    scenario: str | None = None
    patches: dict[str, Any] | None = None
    document = body
    if "scenario" in body:
        document, scenario, patches = _scenario_document(body)
    try:
        problem = ProblemDocument.model_validate(document)
    except ValidationError as exc:
        raise _validation_issues(exc) from None
    return Submission(
        problem=problem,
        document=problem.model_dump(mode="json"),
        scenario=scenario,
        patches=patches,
    )


def check_method_support(submission: Submission) -> None:
    """422 when the selected method cannot handle a feature the problem uses."""
    from worker.solver.methods import check_support

    issues = check_support(submission.problem)
    if issues:
        raise invalid(list(issues))
