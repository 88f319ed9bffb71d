"""Shared building blocks of the problem contract: the strict base model and error helpers.

Every model of the contract rejects unknown fields and non-finite numbers, and every
cross-field check reports its problems at the path of the offending field.
"""

from __future__ import annotations

import itertools
import re
import typing
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Annotated, Any

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    ValidationError,
    ValidatorFunctionWrapHandler,
)
from pydantic import WrapValidator as _WrapValidator
from pydantic_core import InitErrorDetails, PydanticCustomError
from pydantic_core import core_schema as _core_schema

Loc = tuple[str | int, ...]

_KNOWN_ERROR_TYPES: frozenset[str] = frozenset(typing.get_args(_core_schema.ErrorType))


_UNSTORABLE = re.compile("[\x00\ud800-\udfff]")


def _storable(value: str) -> str:
    """``value``, unless it holds a NUL character or an unpaired surrogate (422 naming why)."""
    found = _UNSTORABLE.search(value)
    if found is None:
        return value
    if found.group() == "\x00":
        raise PydanticCustomError(
            "nul_character", "contains a NUL character (U+0000), which cannot be stored"
        )
    raise PydanticCustomError(
        "invalid_text",
        "contains an unpaired surrogate (U+{point}), which is not a character",
        {"point": f"{ord(found.group()):04X}"},
    )


Text = Annotated[str, AfterValidator(_storable)]
"""A free-text string of the contract: any characters but NUL and unpaired surrogates, which
neither PostgreSQL text nor UTF-8 can hold."""


class StrictModel(BaseModel):
    """Base of every contract model: unknown fields and NaN/inf are errors naming the field."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=False)


@dataclass(frozen=True)
class FieldProblem:
    """One validation problem found by a cross-field check: where, a stable code, and why."""

    loc: Loc
    code: str
    message: str
    input: Any = None


def raise_problems(title: str, problems: Sequence[FieldProblem]) -> None:
    """Raise one ``ValidationError`` carrying every problem at its own location (no-op if none).

    Raised inside a validator, pydantic re-roots these locations under the model's own path,
    so ``errors()`` of the enclosing document names e.g. ``("terminal", "altitude_m")``.
    """
    if not problems:
        return
    details = [
        InitErrorDetails(
            type=PydanticCustomError(p.code, p.message),
            loc=p.loc,
            input=p.input,
        )
        for p in problems
    ]
    raise ValidationError.from_exception_data(title, details)


def reissue(error: Any, loc: Loc) -> InitErrorDetails:
    """Rebuild one pydantic error at a new location, keeping its type (and context when known)."""
    error_type: str = error["type"]
    ctx = error.get("ctx")
    if error_type in _KNOWN_ERROR_TYPES and error_type not in ("value_error", "assertion_error"):
        detail = InitErrorDetails(type=error_type, loc=loc, input=error["input"])
        if ctx is not None:
            detail["ctx"] = ctx
        return detail
    message = str(error["msg"]).removeprefix("Value error, ").removeprefix("Assertion failed, ")
    return InitErrorDetails(
        type=PydanticCustomError(error_type, message),
        loc=loc,
        input=error["input"],
    )


def _strip_tag(discriminator: str) -> Callable[[Any, ValidatorFunctionWrapHandler], Any]:
    """Wrap-validator body that drops the union tag pydantic inserts into error locations."""

    def validate(value: Any, handler: ValidatorFunctionWrapHandler) -> Any:
        try:
            return handler(value)
        except ValidationError as exc:
            if isinstance(value, dict):
                tag = value.get(discriminator)
            else:
                tag = getattr(value, discriminator, None)
            if not isinstance(tag, str):
                raise
            details: list[InitErrorDetails] = []
            for error in exc.errors():
                loc: Loc = tuple(error["loc"])
                if loc and loc[0] == tag:
                    loc = loc[1:]
                details.append(reissue(error, loc))
            raise ValidationError.from_exception_data(exc.title, details) from None

    return validate


def untagged_errors(discriminator: str) -> _WrapValidator:
    """Annotation for a discriminated union so its errors sit at the JSON path of the field.

    Pydantic would report ``terminal.altitude_m.range.lo``; with this, ``terminal.altitude_m.lo``.
    """
    return _WrapValidator(_strip_tag(discriminator))


def strictly_increasing(values: Iterable[float]) -> bool:
    """Whether each value is larger than the one before it."""
    items = list(values)
    return all(b > a for a, b in itertools.pairwise(items))
