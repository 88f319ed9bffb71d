"""Path limits against the least-bank flight's first pull-up (``pull_up``).

A limit below that flight's peak is named with both figures. It is a proof that the problem has
no solution when the bound is sound for the vehicle (an angle of attack on a schedule, over the
spherical planet), the problem's flight must descend through the peak's altitude (its terminal
altitude lies below it) and the peak exceeds the limit by more than ``PROOF_MARGIN``; otherwise
it names the likely cause of a failure.
"""

from __future__ import annotations

from dataclasses import dataclass

from worker.solver.prechecks.finding import Finding
from worker.solver.prechecks.pull_up import PullUp, bank_text
from worker.solver.problem import EntryProblem

PROOF_MARGIN = 1.02
"""How far (as a ratio) the least-bank peak must exceed a limit to prove it out of reach: the
verification accepts a flight up to 1 % over a limit, and the NLP that minimizes the peak over
every bank profile came no lower than 0.1 % below the pre-check's peak (bench/lift_up_bound.py)."""


@dataclass(frozen=True)
class LimitView:
    """How a path limit is named and shown."""

    what: str
    field: str
    unit: str
    scale: float
    digits: int


VIEWS = {
    "heat_rate_W_m2": LimitView(
        "heat-rate", "path_constraints.heat_rate.max_W_m2", "kW/m^2", 1e-3, 0
    ),
    "dynamic_pressure_Pa": LimitView(
        "dynamic-pressure", "path_constraints.dynamic_pressure.max_Pa", "kPa", 1e-3, 2
    ),
    "load_factor_g": LimitView("load-factor", "path_constraints.load_factor.max_g", "g", 1.0, 2),
}

SOUND_QUANTITIES = frozenset({"heat_rate_W_m2", "dynamic_pressure_Pa", "load_factor_g"})
"""The path quantities whose least-bank first-pull-up peak no bank profile was found to beat
(bench/lift_up_bound.py: the heating peak to within 0.09 %, dynamic pressure and load factor
by factors of 2 to 10, since theirs come deeper in the flight)."""


def _shown(view: LimitView, value: float) -> str:
    return f"{value * view.scale:,.{view.digits}f} {view.unit}".replace(",", " ")


def _limits(problem: EntryProblem) -> dict[str, float]:
    limits = problem.limits
    found = {
        "heat_rate_W_m2": limits.heat_max_W_m2 if problem.heat_model is not None else None,
        "dynamic_pressure_Pa": limits.dynamic_pressure_max_Pa,
        "load_factor_g": limits.load_factor_max_g,
    }
    return {name: float(value) for name, value in found.items() if value}


def bound_is_sound(problem: EntryProblem, pull_up: PullUp, quantity: str) -> bool:
    """Whether the least-bank peak of ``quantity`` bounds every flight of this problem from
    below: the bank is the only attitude control, over the spherical planet, and the flight must
    reach a terminal altitude below the peak's."""
    if quantity not in SOUND_QUANTITIES or pull_up.attitude.value is not None:
        return False
    if problem.planet_model != "spherical" or problem.alpha_optimized:
        return False
    terminal = problem.terminal.get("altitude_m")
    if terminal is None or terminal.kind not in ("fixed", "range"):
        return False
    highest = terminal.value if terminal.kind == "fixed" else terminal.hi
    if highest is None:
        return False
    peak_radius = 1.0 + pull_up.peaks[quantity].altitude_m / problem.scales.radius_m
    return highest < peak_radius


def limit_findings(problem: EntryProblem, pull_up: PullUp) -> list[Finding]:
    """Every path limit the least-bank flight's first pull-up exceeds, with both figures."""
    found = []
    flight = bank_text(problem)
    for name, limit in _limits(problem).items():
        peak = pull_up.peaks[name]
        if peak.value <= limit:
            continue
        view = VIEWS[name]
        proven = bound_is_sound(problem, pull_up, name) and peak.value > PROOF_MARGIN * limit
        where = (
            f"at t = {peak.time_s:.0f} s, {peak.altitude_m / 1e3:.1f} km, "
            f"{peak.velocity_m_s:.0f} m/s"
        )
        attitude = "" if pull_up.attitude.value is None else f" with {pull_up.attitude.note}"
        lead = (
            f"the {view.what} limit {_shown(view, limit)} is below the first {view.what} peak of "
            f"{flight} flight{attitude}, {_shown(view, peak.value)} ({where})"
        )
        tail = (
            ": no bank profile can hold it"
            if proven
            else ": the limit is likely out of reach from this entry point"
        )
        found.append(
            Finding(
                check="limit_below_pull_up",
                field=view.field,
                message=lead + tail,
                advice=(
                    f"raise {view.field} above {peak.value:.4g} ({_shown(view, peak.value)}, "
                    f"the first {view.what} peak of {flight} flight), or enter shallower or "
                    "slower (initial_state)"
                ),
                proven=proven,
                value=peak.value,
                limit=limit,
                units={"heat_rate_W_m2": "W/m^2", "dynamic_pressure_Pa": "Pa"}.get(name, "g0"),
            )
        )
    return found
