"""Validation errors as a flat list of field issues, for API responses and command-line output."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from pydantic import Field, ValidationError

from app.schemas.base import StrictModel

_MESSAGES: dict[str, str] = {
    "extra_forbidden": "unknown field: not part of the problem contract",
    "missing": "required field is missing",
    "finite_number": "must be a finite number (NaN and infinity are not allowed)",
}


class FieldIssue(StrictModel):
    """One problem with a submitted document: where it is, what is wrong, and a stable code."""

    field: str = Field(
        ...,
        description="Dotted path of the offending field, list indices in brackets, e.g. "
        '"terminal.altitude_m" or "no_fly_zones[0]"; empty for the document itself.',
    )
    message: str = Field(..., description="Human-readable reason.")
    code: str = Field(..., description='Machine-readable error type, e.g. "greater_than".')


def dotted_path(loc: Sequence[str | int]) -> str:
    """Render a pydantic error location as ``a.b[2].c``."""
    path = ""
    for part in loc:
        if isinstance(part, int):
            path += f"[{part}]"
        else:
            path += f".{part}" if path else str(part)
    return path


def _readable(error: Any) -> str:
    """A message for one pydantic error without pydantic's generic prefixes."""
    known = _MESSAGES.get(error["type"])
    if known is not None:
        return known
    ctx = error.get("ctx") or {}
    if error["type"] == "union_tag_invalid":
        return f"unknown value {ctx.get('tag')!r}: must be one of {ctx.get('expected_tags')}"
    if error["type"] == "union_tag_not_found":
        return "required field is missing: it selects which kind of object this is"
    message = str(error["msg"])
    for prefix in ("Value error, ", "Assertion failed, "):
        message = message.removeprefix(prefix)
    return message


_TAG_ERRORS = frozenset({"union_tag_invalid", "union_tag_not_found"})
"""Errors of a discriminated union's tag: pydantic places them at the union, not at its tag."""


def _location(error: Any) -> list[str | int]:
    """Where the error is; a union's missing or unknown tag is placed at the tag itself."""
    loc = list(error["loc"])
    tag = (error.get("ctx") or {}).get("discriminator")
    if error["type"] in _TAG_ERRORS and isinstance(tag, str):
        loc.append(tag.strip("'\""))
    return loc


def issues_from_validation_error(
    exc: ValidationError, limit: int | None = None
) -> list[FieldIssue]:
    """The errors of ``exc`` (the first ``limit``, else all) as ``FieldIssue`` with dotted field
    paths, in pydantic's order; ``exc.error_count()`` tells how many there are in all."""
    errors = exc.errors(include_url=False, include_context=True, include_input=False)
    return [
        FieldIssue(
            field=dotted_path(_location(error)), message=_readable(error), code=error["type"]
        )
        for error in errors[:limit]
    ]
