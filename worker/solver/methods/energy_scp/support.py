"""What paper 000's energy-domain method cannot express, and the consistency of its energy
bounds: refused with a field path and a reason before any work is done."""

from __future__ import annotations

from app.schemas import FieldIssue, ProblemDocument
from worker.solver.methods.base import (
    FINAL_EXTREMES,
    issue,
    objective_issues,
    scheduled_alpha_issues,
    spherical_only_issues,
)

NAME = "energy-scp"
OBJECTIVES = (
    "min_heat_load",
    "min_time",
    *FINAL_EXTREMES,
)


def check_support(doc: ProblemDocument) -> list[FieldIssue]:
    """Features the energy-domain method cannot express, and energy consistency."""
    out: list[FieldIssue] = []
    if doc.final_time.kind == "fixed":
        out.append(
            issue(
                "final_time",
                f"{NAME} cannot fix the final time: energy is its "
                "independent variable and time is an outcome; leave final_time free",
            )
        )
    out.extend(scheduled_alpha_issues(doc, NAME))
    if doc.control_limits.bank_rate_max_deg_s is not None:
        out.append(
            issue(
                "control_limits.bank_rate_max_deg_s",
                f"{NAME} has bank angle as a control, not a state, so it cannot limit its rate",
            )
        )
    limits = doc.control_limits
    if limits.bank_min_deg is not None and limits.bank_min_deg != -limits.bank_max_deg:
        out.append(
            issue(
                "control_limits.bank_min_deg",
                f"{NAME} bounds |bank| symmetrically (its control disc); an asymmetric bank "
                "range needs foh-ptr, or leave bank_min_deg out",
            )
        )
    if doc.no_fly_zones:
        out.append(issue("no_fly_zones", f"{NAME} does not handle no-fly zones"))
    if doc.waypoints:
        out.append(issue("waypoints", f"{NAME} does not handle waypoints"))
    out.extend(spherical_only_issues(doc, NAME))
    out.extend(objective_issues(doc, NAME, OBJECTIVES, "minimize"))
    out.extend(_energy_issues(doc))
    return out


def _energy_issues(doc: ProblemDocument) -> list[FieldIssue]:
    """The energy bounds: e = R0/r - V^2 / (2 g0 R0) (paper 000 eq. 7) must increase."""
    out: list[FieldIssue] = []
    planet = doc.planet
    g0r = planet.surface_gravity_m_s2 * planet.radius_m
    s0 = doc.initial_state
    e0 = planet.radius_m / (planet.radius_m + s0.altitude_m) - s0.velocity_m_s**2 / (2.0 * g0r)
    energy = doc.energy
    if energy is not None and energy.initial is not None and abs(energy.initial - e0) > 1e-4:
        out.append(
            issue(
                "energy.initial",
                f"energy.initial {energy.initial} disagrees with the "
                f"initial state's energy {e0:.6f}; omit it or make them agree",
                "inconsistent",
            )
        )
    alt = doc.terminal.altitude_m
    vel = doc.terminal.velocity_m_s
    ef: float | None = None
    if energy is not None and energy.final is not None:
        ef = energy.final
        if vel.kind != "free":
            out.append(
                issue(
                    "terminal.velocity_m_s",
                    "the terminal speed follows from "
                    "energy.final and the terminal altitude; leave it free",
                    "inconsistent",
                )
            )
    elif alt.kind == "fixed" and vel.kind == "fixed":
        rf = planet.radius_m / (planet.radius_m + alt.value)
        ef = rf - vel.value**2 / (2.0 * g0r)
    else:
        out.append(
            issue(
                "energy.final",
                f"{NAME} needs the final energy: give energy.final, "
                "or a fixed terminal altitude and speed",
                "missing",
            )
        )
    if ef is not None:
        if ef <= e0:
            out.append(
                issue(
                    "energy.final",
                    f"final energy {ef:.6f} is not above the initial "
                    f"energy {e0:.6f}: energy increases during entry",
                    "inconsistent",
                )
            )
        if alt.kind in ("fixed", "range", "soft"):
            lowest = alt.value if alt.kind != "range" else alt.lo
            if planet.radius_m / (planet.radius_m + lowest) <= ef:
                out.append(
                    issue(
                        "terminal.altitude_m",
                        f"at final energy {ef:.6f} the terminal "
                        "altitude leaves no kinetic energy (V^2 <= 0)",
                        "inconsistent",
                    )
                )
    return out
