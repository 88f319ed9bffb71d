"""Options of ``auto``: the methods that accept the problem tried in an order of preference
within one time budget (the rule: ``worker/solver/methods/selection.py``)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, ValidationError, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from app.schemas.base import Loc, reissue
from app.schemas.limits import MAX_NODES, MAX_TIME_LIMIT_S
from app.schemas.methods.common import BoundedOptions, ScpRunOptions

AUTO: Literal["auto"] = "auto"
"""The name of the automatic choice."""

MAX_AUTO_ATTEMPTS = 5
"""Most methods ``auto`` may try for one problem (every method, once)."""


def _detail(loc: Loc, code: str, message: str, value: Any) -> InitErrorDetails:
    """One validation error of auto's options at ``loc``."""
    return InitErrorDetails(type=PydanticCustomError(code, message), loc=loc, input=value)


class AutoOptions(BoundedOptions):
    """Let the service choose: the methods that accept the problem, in the documented order of
    preference, each tried with what the earlier ones left of ``time_limit_s`` until one
    succeeds (converged and verified); with ``cross_check`` a second method (or a second start)
    runs after a success and both values are reported."""

    name: Literal["auto"] = Field(AUTO, description="Method name.")
    time_limit_s: float = Field(
        300.0,
        gt=0,
        le=MAX_TIME_LIMIT_S,
        description="CPU-time limit of the whole run, every attempt together, s of the solving "
        f"process's CPU time, in (0, {MAX_TIME_LIMIT_S:g}]; each attempt gets what the earlier "
        "ones left (a method's own time_limit_s in overrides caps its attempt), and a "
        "wall-clock safety limit of 4 x as many seconds ends the whole run.",
    )
    max_attempts: int = Field(
        3,
        ge=1,
        le=MAX_AUTO_ATTEMPTS,
        description=f"Most methods tried for an answer, 1..{MAX_AUTO_ATTEMPTS} (the cross-check's "
        "run is not counted).",
    )
    cross_check: bool | None = Field(
        None,
        description="After a success, run the next methods that accept the problem until one "
        "succeeds (or, when there is none, the same method from a global-search start) and "
        "report both values; a difference over 0.5 % is flagged (a local optimum is possible) "
        "and the better verified answer is kept. null: on for the problem classes known to "
        "have several local optima (an objective on the final latitude or longitude: the turn "
        "direction and bank-sign choices give separate optima; a minimum heat load whose "
        "answer skips, climbing more than 7.2 km from a low point: each skip's depth is a "
        "choice), off otherwise.",
    )
    nodes: int | None = Field(
        None,
        ge=3,
        le=MAX_NODES,
        description="Nodes of every method tried (null: each method's own default); a method's "
        "own nodes in overrides win. A method that cannot run with this count is not tried.",
    )
    overrides: dict[str, dict[str, Any]] = Field(
        default_factory=dict,
        description='Options of a method when auto tries it, by method name, e.g. {"foh-ptr": '
        '{"nodes": 60, "max_iterations": 80}}; each is checked against that method\'s options '
        "(GET /v1/methods).",
    )

    @model_validator(mode="after")
    def _overrides_fit(self) -> AutoOptions:
        from app.schemas.methods import METHOD_OPTIONS

        details: list[InitErrorDetails] = []
        for name, given in self.overrides.items():
            options_type = METHOD_OPTIONS.get(name)
            if options_type is None:
                known = ", ".join(METHOD_OPTIONS)
                details.append(
                    _detail(
                        ("overrides", name),
                        "unknown_method",
                        f"unknown method {name!r}; auto tries {known}",
                        name,
                    )
                )
            elif given.get("name", name) != name:
                details.append(
                    _detail(
                        ("overrides", name, "name"),
                        "inconsistent",
                        f"the options of {name} name another method; leave name out",
                        given.get("name"),
                    )
                )
            else:
                try:
                    options_type.model_validate({**given, "name": name})
                except ValidationError as exc:
                    details += [reissue(e, ("overrides", name, *e["loc"])) for e in exc.errors()]
        if details:
            raise ValidationError.from_exception_data(type(self).__name__, details)
        return self

    def options_for(self, name: str, defaults: dict[str, Any] | None = None) -> ScpRunOptions:
        """The options of method ``name`` when auto tries it: its defaults, then auto's own
        ``defaults`` for it (the rule's, for the problem's class), then ``nodes``, then its
        overrides. Raises ``ValidationError`` when the method cannot take them (e.g. too few
        nodes for it)."""
        from app.schemas.methods import METHOD_OPTIONS

        given: dict[str, Any] = dict(defaults or {})
        if self.nodes is not None:
            given["nodes"] = self.nodes
        given.update(self.overrides.get(name, {}))
        return METHOD_OPTIONS[name].model_validate({**given, "name": name})
