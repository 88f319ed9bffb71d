"""Where and when the vehicle can end: families of constant-bank flights from the entry point.

Each flight holds one bank, from the least the control limits allow to the largest, on one side,
from the entry state to the problem's end (its terminal altitude or final energy; a fixed final
time is not imposed: how long each flight takes is what it is compared with). The least-bank
flight covers the longest ground track, the largest bank ends nearest, and the bearings their
tracks reach (seen from the entry point) bound how far a path can swing aside. A flight that
reverses its bank to fly straight covers its whole ground track, one that turns one way ends
nearer for the same duration: a fixed final time outside the durations that end at the
target's distance cannot end there.

Held banks are not the optimal controls, so every figure comes with a margin and names a likely
cause of a failure, never a proof.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from worker.solver.geometry import CircleZone
from worker.solver.prechecks.finding import Finding
from worker.solver.prechecks.flight import Flight, fly, least_bank, lift_up_attitudes
from worker.solver.prechecks.sphere import bearing, central_angle, track_frame
from worker.solver.problem import EntryProblem

Array = np.ndarray

BANKS_DEG = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0)
"""The banks of a family (clipped to the control limits, each flown once)."""
RTOL = 1e-5
"""The families' relative tolerance: end points and durations to a few metres and
milliseconds (against 1e-8), far below the margins of these checks."""
REACH_MARGIN = 0.05
"""How far (share of the target's distance, or of a duration) a target must lie beyond every
flight, or a final time outside the durations that reach it, before it is named: the best bank
profile reaches somewhat beyond what held banks do."""
TURN_MARGIN = 1.25
"""How much wider (ratio) than any held bank's track a zone's sides must lie, in bearing from
the entry point, before the zone is named: a bank that varies along the flight turns wider."""


@dataclass
class Family:
    """Constant-bank flights on one side, ordered by bank magnitude."""

    flights: list[Flight]
    reached: Array
    """Whether each flight reached the problem's end (terminal altitude or final energy)."""
    distance: Array
    """Great-circle distance from the entry point to each end point, km."""
    ground: Array
    """Length of each ground track, km."""
    duration: Array
    """Each flight's duration, s."""
    tracks: list[tuple[Array, Array]]
    """Each flight's ground track seen from the entry point: distance (km) and bearing against
    the entry heading (deg, positive to the right), at every sample."""


@dataclass(frozen=True)
class Target:
    """The point a problem must end at: latitude and longitude (rad), whether both are fixed."""

    latitude: float
    longitude: float
    fixed: bool

    def text(self) -> str:
        return f"({math.degrees(self.longitude):.2f} E, {math.degrees(self.latitude):.2f} N)"


def target_of(problem: EntryProblem) -> Target | None:
    """The problem's target point when its latitude and longitude are both fixed or soft."""
    lat, lon = problem.terminal.get("latitude_deg"), problem.terminal.get("longitude_deg")
    if lat is None or lon is None or lat.value is None or lon.value is None:
        return None
    if lat.kind not in ("fixed", "soft") or lon.kind not in ("fixed", "soft"):
        return None
    return Target(lat.value, lon.value, lat.kind == "fixed" and lon.kind == "fixed")


def _banks(problem: EntryProblem, side: float) -> list[float]:
    """A family's banks (rad) on ``side`` (+1 right, -1 left), within the control limits."""
    values = [least_bank(problem)]
    for b in BANKS_DEG[1:]:
        value = min(max(side * math.radians(b), problem.bank_min), problem.bank_max)
        if all(abs(value - seen) > 1e-9 for seen in values):
            values.append(value)
    return values


def constant_bank_family(problem: EntryProblem, side: float) -> Family:
    """Fly each bank of the family on ``side`` to the problem's end."""
    attitude = lift_up_attitudes(problem)[-1]  # the schedule, or the largest held lift
    free = dataclasses.replace(problem, final_time=None)
    flights = [fly(free, bank, attitude, rtol=RTOL) for bank in _banks(problem, side)]
    km = problem.scales.radius_m / 1e3
    lat0, lon0 = float(problem.y0[2]), float(problem.y0[1])
    distance, ground, tracks = [], [], []
    for f in flights:
        lat, lon = f.y[2], f.y[1]
        distance.append(float(central_angle(lat0, lon0, lat[-1], lon[-1])) * km)
        ground.append(float(np.sum(central_angle(lat[:-1], lon[:-1], lat[1:], lon[1:]))) * km)
        tracks.append(
            (central_angle(lat0, lon0, lat, lon) * km, _off_heading_deg(problem, lat, lon))
        )
    return Family(
        flights=flights,
        reached=np.array([f.ended in ("altitude", "energy") for f in flights]),
        distance=np.array(distance),
        ground=np.array(ground),
        duration=np.array([f.duration_s for f in flights]),
        tracks=tracks,
    )


def _time_for(distances: Array, durations: Array, d: float) -> float | None:
    """The duration at which a family's distance equals ``d`` (linear between flights), or None
    outside its distances."""
    order = np.argsort(distances)
    x, y = distances[order], durations[order]
    if d < x[0] or d > x[-1]:
        return None
    return float(np.interp(d, x, y))


def _off_heading_deg(problem: EntryProblem, lat: Array | float, lon: Array | float) -> Array:
    """The bearing of points from the entry point against the entry heading, deg (positive to
    the right)."""
    lat0, lon0, psi0 = float(problem.y0[2]), float(problem.y0[1]), float(problem.y0[5])
    off = bearing(lat0, lon0, lat, lon) - psi0
    return np.degrees(np.arctan2(np.sin(off), np.cos(off)))


def fan(families: dict[float, Family], beyond_km: float) -> dict[float, float]:
    """How far to each side of the entry heading (deg of bearing) the families' tracks reach at
    ``beyond_km`` or more from the entry point: +1 the right, -1 the left."""
    out = {}
    for side in (1.0, -1.0):
        widest = 0.0
        for family in families.values():
            for distance, off in family.tracks:
                far = distance >= beyond_km
                if far.any():
                    widest = max(widest, float(np.max(side * off[far])))
        out[side] = widest
    return out


def reach_findings(problem: EntryProblem) -> list[Finding]:
    """A fixed target out of reach, a zone across the whole corridor to the target, a fixed
    final time far from what a flight to the target (or to the problem's end) takes."""
    families = {side: constant_bank_family(problem, side) for side in (1.0, -1.0)}
    if not any(f.reached.any() for f in families.values()):
        return []
    target = target_of(problem)
    found: list[Finding] = []
    if target is not None and target.fixed:
        found += _target_findings(problem, families, target)
    if target is not None:
        found += _corridor_findings(problem, families, target)
    found += _final_time_findings(problem, families, target)
    return found


def _reached(families: dict[float, Family], name: str) -> Array:
    """A figure of every flight of both families that reached the problem's end."""
    return np.concatenate([getattr(f, name)[f.reached] for f in families.values()])


def _km(value: float) -> str:
    return f"{value:,.0f} km".replace(",", " ")


SOFTEN = (
    'or make it soft (terminal.latitude_deg and terminal.longitude_deg: {"kind": "soft", '
    '"value": ..., "weight": ...})'
)


def _target_findings(
    problem: EntryProblem, families: dict[float, Family], target: Target
) -> list[Finding]:
    km = problem.scales.radius_m / 1e3
    lat0, lon0 = float(problem.y0[2]), float(problem.y0[1])
    d = float(central_angle(lat0, lon0, target.latitude, target.longitude)) * km
    longest = float(np.max(_reached(families, "ground")))
    nearest = float(np.min(_reached(families, "distance")))
    field = "terminal.longitude_deg, terminal.latitude_deg"
    lead = f"the target {target.text()} is {_km(d)} from the entry point"
    if d > longest * (1.0 + REACH_MARGIN):
        message = (
            f"{lead}; the longest flight found ({_least(problem)}) covers {_km(longest)} "
            "before it ends: the target is likely out of reach"
        )
        advice = f"move the target nearer, or enter faster or higher (initial_state), {SOFTEN}"
        return [Finding("target_out_of_reach", field, message, advice, False, longest, d, "km")]
    if d < nearest * (1.0 - REACH_MARGIN):
        message = (
            f"{lead}; the shortest flight found (the largest bank held) ends {_km(nearest)} "
            "from it: the target is likely too near to lose the entry energy on the way"
        )
        advice = f"move the target farther, or enter slower (initial_state), {SOFTEN}"
        return [Finding("target_out_of_reach", field, message, advice, False, nearest, d, "km")]
    return []


def _least(problem: EntryProblem) -> str:
    bank = math.degrees(least_bank(problem))
    return "full lift-up" if bank == 0.0 else f"bank {bank:g} deg"


def _corridor_findings(
    problem: EntryProblem, families: dict[float, Family], target: Target
) -> list[Finding]:
    """Zones across the direct path to the target whose sides lie at bearings (seen from the
    entry point) that no held bank's track reaches at the zone's distance."""
    found = []
    km = problem.scales.radius_m / 1e3
    lat0, lon0 = float(problem.y0[2]), float(problem.y0[1])
    to_target = float(bearing(lat0, lon0, target.latitude, target.longitude))
    for index, zone in enumerate(problem.no_fly_zones):
        radius = _radius_rad(zone)
        along, cross = track_frame(lat0, lon0, to_target, zone.latitude, zone.longitude)
        if along <= 0.0 or abs(float(cross)) >= radius:
            continue  # behind the entry point, or beside the direct path
        centre = float(central_angle(lat0, lon0, zone.latitude, zone.longitude))
        half = math.degrees(math.asin(min(math.sin(radius) / math.sin(centre), 1.0)))
        off = float(_off_heading_deg(problem, zone.latitude, zone.longitude))
        right, left = off + half, half - off  # bearings that pass it on the right, the left
        reach = fan(families, (centre - radius) * km)
        if right <= TURN_MARGIN * reach[1.0] or left <= TURN_MARGIN * reach[-1.0]:
            continue
        label = f"no-fly zone {zone.name!r}" if zone.name else f"no-fly zone {index}"
        field = f"no_fly_zones[{index}]"
        message = (
            f"{label} (radius {_km(radius * km)}, its centre {_km(centre * km)} from the entry "
            f"point) lies across the direct path to the target: passing it takes a track "
            f"{right:.1f} deg to the right or {left:.1f} deg to the left of the entry heading, "
            f"and no held bank's track gets wider than {reach[1.0]:.1f} deg right and "
            f"{reach[-1.0]:.1f} deg left that far out: the zone likely blocks the whole corridor"
        )
        advice = f"move or shrink {field}, or move the entry point or the target"
        need, widest = min(right, left), max(reach.values())
        found.append(
            Finding("zone_blocks_corridor", field, message, advice, False, need, widest, "deg")
        )
    return found


def _radius_rad(zone: CircleZone) -> float:
    """A zone's radius as a great-circle angle (a lat_lon zone's, read as one)."""
    return zone.radius


def _final_time_findings(
    problem: EntryProblem, families: dict[float, Family], target: Target | None
) -> list[Finding]:
    if problem.final_time is None:
        return []
    final = problem.final_time * problem.scales.time_s
    km = problem.scales.radius_m / 1e3
    durations = _reached(families, "duration")
    if target is not None:
        lat0, lon0 = float(problem.y0[2]), float(problem.y0[1])
        d = float(central_angle(lat0, lon0, target.latitude, target.longitude)) * km
        straight = _time_for(_reached(families, "ground"), durations, d)
        turning = _time_for(_reached(families, "distance"), durations, d)
        if straight is None or turning is None:
            return []
        low, high = min(straight, turning), max(straight, turning)
        need = (
            f"flights from the entry point that end at the target's distance ({_km(d)}) last "
            f"{low:.0f}-{high:.0f} s"
        )
    else:
        low, high = float(np.min(durations)), float(np.max(durations))
        need = (
            f"flights from the entry point to the problem's end last {low:.0f}-{high:.0f} s "
            "(the largest bank held to the least)"
        )
    if low * (1.0 - REACH_MARGIN) <= final <= high * (1.0 + REACH_MARGIN):
        return []
    longer = final > high
    longest = float(np.max(durations))
    # a flight can last longer than the straight or the turning one by wandering (S-turns, a
    # dog-leg, another angle of attack) within the longest flight's duration: only maybe
    wander = longer and target is not None and final <= longest * (1.0 + REACH_MARGIN)
    suggest = 10.0 * round(0.05 * (low + high))
    if not longer:
        verdict = f"the final time {final:.0f} s is shorter than the flight needs: {need}"
    elif wander:
        verdict = (
            f"the final time {final:.0f} s is longer than flights that end at the target take: "
            f"{need}; a longer flight must wander on the way (S-turns, a dog-leg) and may not "
            f"exist, though the longest flight found lasts {longest:.0f} s"
        )
    else:
        verdict = (
            f"the final time {final:.0f} s is longer than the flight needs: {need}; the "
            f"longest flight found lasts {longest:.0f} s"
        )
    message = f"{verdict} (banks held constant)"
    advice = (
        f"set final_time.value_s near {suggest:.0f} s, or a free final time "
        '(final_time: {"kind": "free"}) with a method that takes one'
    )
    return [
        Finding(
            "final_time",
            "final_time.value_s",
            message,
            advice,
            False,
            final,
            high if longer else low,
            "s",
            possible=wander,
        )
    ]
