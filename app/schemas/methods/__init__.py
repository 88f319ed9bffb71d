"""Solution methods and their options: one options model per method, one file per method.

``METHOD_OPTION_TYPES`` is the one list of methods: the problem contract's ``MethodSpec`` union
(those methods and ``auto``, which chooses among them) and the solver's method registry
(``worker.solver.methods.registry``) are both built from it. To add a method: write its options
model (a ``name`` literal, ``nodes``, the shared budgets of ``ScpRunOptions``) in a file here,
add it to ``METHOD_OPTION_TYPES``, and write its solver package
``worker/solver/methods/<name with underscores>/``; ``auto`` then considers it too.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Final, Union

from pydantic import BeforeValidator, Field

from app.schemas.base import untagged_errors
from app.schemas.methods.auto import AUTO, MAX_AUTO_ATTEMPTS, AutoOptions
from app.schemas.methods.cheb_scvx import ChebScvxOptions, ChebStopTolerance, ChebTrustRegion
from app.schemas.methods.common import BoundedOptions, ScpRunOptions
from app.schemas.methods.energy_scp import EnergyScpOptions, EnergyStopTolerance
from app.schemas.methods.foh_ptr import FohPtrOptions, FohStopTolerance
from app.schemas.methods.hp_scp import HpScpOptions, HpStopTolerance
from app.schemas.methods.lgl_sqp import GlobalGuessOptions, LglSqpOptions

METHOD_OPTION_TYPES: Final[tuple[type[ScpRunOptions], ...]] = (
    EnergyScpOptions,
    FohPtrOptions,
    HpScpOptions,
    ChebScvxOptions,
    LglSqpOptions,
)
"""Every method's options model: the one place a method is registered."""

DEFAULT_METHOD: Final[str] = AUTO
"""Method used when a document names none: ``auto`` chooses among the methods."""


def method_name(options_type: type[ScpRunOptions]) -> str:
    """The method name an options model declares (the default of its ``name`` literal)."""
    name = options_type.model_fields["name"].default
    assert isinstance(name, str), options_type
    return name


METHOD_OPTIONS: dict[str, type[ScpRunOptions]] = {method_name(t): t for t in METHOD_OPTION_TYPES}
"""Options model of every method, by method name."""

METHOD_NAMES: tuple[str, ...] = tuple(METHOD_OPTIONS)
"""Names of the methods that solve (``auto`` chooses among them)."""


def default_method_options() -> MethodSpec:
    """The default method (``auto``) with its default options."""
    return AutoOptions()


def _default_name(value: Any) -> Any:
    """A method object without ``name`` selects the default method."""
    if isinstance(value, dict) and "name" not in value:
        return {**value, "name": DEFAULT_METHOD}
    return value


_SELECTABLE = (*METHOD_OPTION_TYPES, AutoOptions)
"""Every method's options and auto's: the variants of a document's ``method``."""

if TYPE_CHECKING:
    MethodSpec = ScpRunOptions | AutoOptions
else:
    MethodSpec = Annotated[
        Annotated[Union[_SELECTABLE], Field(discriminator="name")],  # noqa: UP007
        untagged_errors("name"),
        BeforeValidator(_default_name),
    ]
"""The solution method and its options, selected by ``name`` (statically: a method's shared
base, or ``auto``'s options)."""

__all__ = [
    "AUTO",
    "DEFAULT_METHOD",
    "MAX_AUTO_ATTEMPTS",
    "METHOD_NAMES",
    "METHOD_OPTIONS",
    "METHOD_OPTION_TYPES",
    "AutoOptions",
    "BoundedOptions",
    "ChebScvxOptions",
    "ChebStopTolerance",
    "ChebTrustRegion",
    "EnergyScpOptions",
    "EnergyStopTolerance",
    "FohPtrOptions",
    "FohStopTolerance",
    "GlobalGuessOptions",
    "HpScpOptions",
    "HpStopTolerance",
    "LglSqpOptions",
    "MethodSpec",
    "ScpRunOptions",
    "default_method_options",
    "method_name",
]
