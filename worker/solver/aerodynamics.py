"""Aerodynamic models and angle-of-attack schedules built from the problem's specification.

The models live in ``aero_models`` (interface, polynomial, parabolic polar), ``aero_tables``
(tabulated CL/CD) and ``alpha_schedules``; this module builds them from a schema object or a
plain dict.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from worker.solver.aero_models import AeroModel, ParabolicPolarAero, PolynomialAero
from worker.solver.aero_tables import TableAero
from worker.solver.alpha_schedules import (
    AlphaSchedule,
    ConstantAlpha,
    TableAlpha,
    VelocityScheduleAlpha,
)

_MISSING = object()


def _spec_value(spec: Any, name: str, default: Any = _MISSING) -> Any:
    """Field ``name`` of a mapping or attribute object, else ``default`` (KeyError if none)."""
    value = spec.get(name, default) if isinstance(spec, Mapping) else getattr(spec, name, default)
    if value is _MISSING:
        raise KeyError(f"specification has no field {name!r}")
    return value


def aero_from_spec(spec: Any) -> AeroModel:
    """Build the aerodynamic model described by a schema object or plain dict (``model``)."""
    model = _spec_value(spec, "model")
    if model == "polynomial":
        return PolynomialAero(
            list(_spec_value(spec, "cl_coefficients")),
            list(_spec_value(spec, "cd_coefficients")),
            _spec_value(spec, "cd_argument"),
        )
    if model == "parabolic_polar":
        return ParabolicPolarAero(
            cl_star=float(_spec_value(spec, "cl_star")),
            cd0=float(_spec_value(spec, "cd0")),
            k_induced=float(_spec_value(spec, "k_induced")),
        )
    if model == "table":
        return TableAero(
            _spec_value(spec, "alpha_deg"),
            _spec_value(spec, "mach"),
            _spec_value(spec, "cl"),
            _spec_value(spec, "cd"),
            _spec_value(spec, "interpolation", "linear"),
        )
    raise ValueError(
        f"unknown aerodynamics model {model!r}; expected 'polynomial', 'parabolic_polar' or 'table'"
    )


def alpha_schedule_from_spec(spec: Any) -> AlphaSchedule | None:
    """Build the angle-of-attack schedule of a schema object or dict; None when optimized."""
    mode = _spec_value(spec, "mode")
    if mode == "velocity_schedule":
        return VelocityScheduleAlpha(
            alpha_max_deg=float(_spec_value(spec, "alpha_max_deg", 40.0)),
            velocity_break_m_s=float(_spec_value(spec, "velocity_break_m_s", 4570.0)),
            slope_coefficient=float(_spec_value(spec, "slope_coefficient", 0.20705)),
            velocity_scale_m_s=float(_spec_value(spec, "velocity_scale_m_s", 340.0)),
        )
    if mode == "table":
        return TableAlpha(_spec_value(spec, "velocity_m_s"), _spec_value(spec, "alpha_deg"))
    if mode == "constant":
        return ConstantAlpha(float(_spec_value(spec, "alpha_deg")))
    if mode == "optimized":
        return None
    raise ValueError(
        f"unknown angle-of-attack mode {mode!r}; "
        "expected 'velocity_schedule', 'table', 'constant' or 'optimized'"
    )
