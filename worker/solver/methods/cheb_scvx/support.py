"""What paper 001's Chebyshev SCvx cannot express: refused with a field path and a reason before
any work is done."""

from __future__ import annotations

from app.schemas import FieldIssue, ProblemDocument
from worker.solver.aero_models import LiftShareAero
from worker.solver.aerodynamics import aero_from_spec
from worker.solver.methods.base import FINAL_EXTREMES, issue, objective_issues
from worker.solver.methods.cheb_scvx.lift_share import mach_samples

NAME = "cheb-scvx"
OBJECTIVES = ("min_time", "max_terminal_velocity", "min_heat_load", *FINAL_EXTREMES)


def check_support(doc: ProblemDocument) -> list[FieldIssue]:
    """Features the method cannot express."""
    out: list[FieldIssue] = []
    alpha = doc.vehicle.angle_of_attack
    optimized = alpha is not None and alpha.mode == "optimized"
    if optimized:
        out.extend(_lift_share_issues(doc))
    limits = doc.control_limits
    if limits.bank_max_deg >= 90.0 or limits.bank_lower_deg <= -90.0:
        out.append(
            issue(
                "control_limits.bank_max_deg",
                f"{NAME} bounds the bank by linear cuts u2 <= tan(sigma_max) u1 (paper 001 eq. "
                "41), which need the bank range inside (-90, 90) deg",
            )
        )
    if limits.alpha_rate_max_deg_s is not None:
        out.append(
            issue(
                "control_limits.alpha_rate_max_deg_s",
                f"{NAME} flies a normalized lift, not an angle of attack",
            )
        )
    if doc.initial_state.bank_deg is not None:
        out.append(
            issue("initial_state.bank_deg", f"{NAME} leaves the initial bank free; leave it out")
        )
    hr = doc.path_constraints.heat_rate
    polar = doc.vehicle.aerodynamics.model == "parabolic_polar"
    if hr is not None and hr.alpha_polynomial and polar:
        out.append(
            issue(
                "path_constraints.heat_rate.alpha_polynomial",
                f"{NAME} has no angle of attack for a heating factor on a parabolic polar "
                "vehicle (its normalized lift has none): give CL, CD in the angle of attack",
            )
        )
    for key in ("altitude_m", "longitude_deg", "latitude_deg", "velocity_m_s",
                "flight_path_angle_deg", "heading_deg"):  # fmt: skip
        if getattr(doc.terminal, key).kind == "soft":
            out.append(
                issue(
                    f"terminal.{key}",
                    f"{NAME} takes fixed, range or free terminal conditions, not soft targets",
                )
            )
    target = doc.target_point_deg()
    if doc.waypoints and target is None:
        out.append(
            issue(
                "waypoints",
                f"{NAME} places waypoints on segments of the route to a target point; give the "
                "terminal latitude and longitude",
            )
        )
    if doc.waypoints and doc.initial_guess is not None:
        out.append(
            issue(
                "initial_guess",
                f"{NAME} starts a problem with waypoints from its own route guess; leave "
                "initial_guess out",
            )
        )
    if doc.energy is not None:
        out.append(
            issue("energy", f"{NAME} works in time and ignores energy bounds; leave energy out")
        )
    out.extend(objective_issues(doc, NAME, OBJECTIVES, "optimize"))
    return out


def _lift_share_issues(doc: ProblemDocument) -> list[FieldIssue]:
    """An optimized angle of attack is flown as the lift share lam = CL(alpha, M) /
    CL(alpha_max, M): no initial value or rate bound, and CL must increase with alpha."""
    spec = doc.vehicle.angle_of_attack
    assert spec is not None and spec.mode == "optimized"
    out: list[FieldIssue] = []
    if spec.rate_max_deg_s is not None:
        out.append(
            issue(
                "vehicle.angle_of_attack.rate_max_deg_s",
                f"{NAME} derives the angle of attack from the normalized lift and bounds no rate "
                "of it; leave it out",
            )
        )
    if spec.initial_deg is not None:
        out.append(
            issue(
                "vehicle.angle_of_attack.initial_deg",
                f"{NAME} leaves the initial angle of attack free; leave it out",
            )
        )
    aero = aero_from_spec(doc.vehicle.aerodynamics)
    try:
        LiftShareAero.checked(aero, spec.min_deg, spec.max_deg, mach_samples(aero, 1.0))
    except ValueError as exc:
        out.append(issue("vehicle.angle_of_attack", f"{NAME}: {exc}"))
    return out
