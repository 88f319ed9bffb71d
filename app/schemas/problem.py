"""The problem document: one versioned JSON object describing an entry trajectory optimization."""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field, model_validator

from app.schemas.base import FieldProblem, StrictModel, Text, raise_problems
from app.schemas.constraints import ControlLimits, PathConstraints
from app.schemas.examples import RLV_MIN_HEAT_LOAD
from app.schemas.guess import InitialGuess
from app.schemas.limits import MAX_NO_FLY_ZONES, MAX_PHASES, MAX_WAYPOINTS
from app.schemas.methods import (
    ChebScvxOptions,
    FohPtrOptions,
    MethodSpec,
    default_method_options,
)
from app.schemas.methods.cheb_scvx import default_resolution as cheb_default_resolution
from app.schemas.methods.foh_ptr import default_nodes as foh_default_nodes
from app.schemas.objective import ObjectiveInput
from app.schemas.phases import Phase
from app.schemas.planet import Planet
from app.schemas.regions import NoFlyZone, Waypoint
from app.schemas.state import EnergyBounds, FinalTime, FixedFinalTime, FreeFinalTime, InitialState
from app.schemas.terminal import FixedSpec, FreeSpec, RangeSpec, SoftSpec, TerminalConditions
from app.schemas.vehicle import Vehicle

SCHEMA_VERSION: Literal["1.0"] = "1.0"


class ProblemDocument(StrictModel):
    """An entry trajectory optimization problem: vehicle, planet, boundary conditions,
    constraints, objective and solution method. SI units and degrees throughout."""

    model_config = ConfigDict(
        title="ProblemDocument",
        json_schema_extra={"examples": [RLV_MIN_HEAT_LOAD]},
    )

    schema_version: Literal["1.0"] = Field(
        SCHEMA_VERSION, description="Version of this contract; only 1.0 exists."
    )
    name: Text | None = Field(None, max_length=200, description="Short label of the problem.")
    description: Text | None = Field(
        None, max_length=10_000, description="Free-text description of the problem."
    )
    vehicle: Vehicle = Field(..., description="The entry vehicle.")
    planet: Planet = Field(..., description="Planet shape, gravity, rotation and atmosphere.")
    initial_state: InitialState = Field(..., description="State at the entry interface.")
    terminal: TerminalConditions = Field(
        default_factory=TerminalConditions,
        description="Conditions on the final state; unspecified components are free.",
    )
    final_time: FinalTime = Field(
        default_factory=FreeFinalTime, description="Free (default) or fixed final time."
    )
    energy: EnergyBounds | None = Field(
        None,
        description="Energy interval for energy-domain methods; none = derived from the initial "
        "state and the terminal altitude and speed.",
    )
    path_constraints: PathConstraints = Field(
        default_factory=PathConstraints, description="Heat rate, dynamic pressure, load factor."
    )
    control_limits: ControlLimits = Field(
        default_factory=ControlLimits, description="Bank angle and control rate bounds."
    )
    phases: list[Phase] = Field(
        default_factory=list,
        max_length=MAX_PHASES,
        description=f"Linked legs of the flight, in order, at most {MAX_PHASES}; each has its own "
        "duration bounds, end conditions, control bounds, thrust limit and path constraints. "
        "Empty (the default): one phase, bounded by terminal, final_time, control_limits and "
        "path_constraints. With phases, terminal and final_time stay free and energy is left "
        "out: the last phase's end holds the final conditions.",
    )
    no_fly_zones: list[NoFlyZone] = Field(
        default_factory=list,
        max_length=MAX_NO_FLY_ZONES,
        description=f"Circular zones to avoid, at most {MAX_NO_FLY_ZONES}.",
    )
    waypoints: list[Waypoint] = Field(
        default_factory=list,
        max_length=MAX_WAYPOINTS,
        description=f"Circular regions to overfly in order, at most {MAX_WAYPOINTS}.",
    )
    objective: ObjectiveInput = Field(
        ...,
        description="What to optimize: a list of weighted terms, or a single term name such as "
        '"min_heat_load".',
    )
    method: MethodSpec = Field(
        default_factory=default_method_options,
        description='Solution method and its options; default {"name": "auto"}: the methods '
        "that accept the problem tried in a documented order (docs/problem-contract.md, "
        '"Method"); an object without name is auto\'s.',
    )
    initial_guess: InitialGuess | None = Field(
        None,
        description="Start from an earlier answer: one of your finished jobs (from_job) or an "
        "explicit trajectory; null: the method's own guess.",
    )

    @model_validator(mode="after")
    def _consistent(self) -> ProblemDocument:
        problems = [
            *self._terminal_altitude_problems(),
            *self._no_fly_zone_problems(),
            *self._waypoint_problems(),
            *self._final_time_problems(),
            *self._initial_bank_problems(),
            *self._phase_problems(),
            *self._propulsion_problems(),
        ]
        raise_problems("ProblemDocument", problems)
        self._class_default_nodes()
        return self

    def class_resolution(self, name: str) -> dict[str, int]:
        """Method ``name``'s resolution for this problem's class when its document gives none:
        foh-ptr's nodes, cheb-scvx's nodes and intervals (their fields describe the rules);
        empty for the other methods."""
        heat_load = "min_heat_load" in self.objective.names()
        if name == "cheb-scvx":
            nodes, intervals = cheb_default_resolution(heat_load)
            return {"nodes": nodes, "intervals": intervals}
        if name != "foh-ptr":
            return {}
        attack = self.vehicle.angle_of_attack
        held = self.vehicle.aerodynamics.model == "parabolic_polar" or (
            attack is not None and attack.mode == "optimized"
        )
        free = self.final_time.kind == "free"
        return {"nodes": foh_default_nodes(free, heat_load, held)}

    def _class_default_nodes(self) -> None:
        """The class's resolution (``class_resolution``) where the document names foh-ptr or
        cheb-scvx and gives neither nodes nor intervals, written into the document so that it
        shows what was solved."""
        method = self.method
        if not isinstance(method, FohPtrOptions | ChebScvxOptions):
            return
        if {"nodes", "intervals"} & method.model_fields_set:
            return
        for key, value in self.class_resolution(method.name).items():
            setattr(method, key, value)

    def _terminal_altitude_problems(self) -> list[FieldProblem]:
        spec = self.terminal.altitude_m
        if isinstance(spec, FixedSpec):
            floor, key = spec.value, "value"
        elif isinstance(spec, RangeSpec):
            floor, key = spec.lo, "lo"
        else:
            return []
        initial = self.initial_state.altitude_m
        if floor <= initial:
            return []
        return [
            FieldProblem(
                ("terminal", "altitude_m"),
                "terminal_above_initial",
                f"terminal altitude ({key} {floor:g} m) is above the initial altitude "
                f"({initial:g} m)",
                floor,
            )
        ]

    def final_conditions(self) -> TerminalConditions:
        """Conditions on the final state: ``terminal``, or the last phase's ``end`` with phases."""
        return self.phases[-1].end if self.phases else self.terminal

    def target_point_deg(self) -> tuple[float, float] | None:
        """Final (latitude, longitude) in degrees when both are fixed or soft targets, else None."""
        final = self.final_conditions()
        lat, lon = final.latitude_deg, final.longitude_deg
        if isinstance(lat, FixedSpec | SoftSpec) and isinstance(lon, FixedSpec | SoftSpec):
            return lat.value, lon.value
        return None

    def _no_fly_zone_problems(self) -> list[FieldProblem]:
        radius = self.planet.radius_m
        start = (self.initial_state.latitude_deg, self.initial_state.longitude_deg)
        target = self.target_point_deg()
        problems: list[FieldProblem] = []
        for i, zone in enumerate(self.no_fly_zones):
            label = f"no-fly zone {zone.name!r}" if zone.name else f"no-fly zone {i}"
            if self.planet.model == "flat" and zone.metric != "lat_lon":
                problems.append(
                    FieldProblem(
                        ("no_fly_zones", i, "metric"),
                        "metric_of_model",
                        f"{label}: on the flat-Earth planet model distances are map distances; "
                        'give "metric": "lat_lon"',
                        zone.metric,
                    )
                )
            if zone.contains_point(*start, radius):
                problems.append(
                    FieldProblem(
                        ("no_fly_zones", i),
                        "zone_contains_initial_point",
                        f"{label} contains the initial point "
                        f"(latitude {start[0]:g} deg, longitude {start[1]:g} deg)",
                    )
                )
            if target is not None and zone.contains_point(*target, radius):
                problems.append(
                    FieldProblem(
                        ("no_fly_zones", i),
                        "zone_contains_target",
                        f"{label} contains the target point "
                        f"(latitude {target[0]:g} deg, longitude {target[1]:g} deg)",
                    )
                )
        return problems

    def _waypoint_problems(self) -> list[FieldProblem]:
        first_index: dict[int, int] = {}
        problems: list[FieldProblem] = []
        for i, waypoint in enumerate(self.waypoints):
            if waypoint.order in first_index:
                problems.append(
                    FieldProblem(
                        ("waypoints", i, "order"),
                        "duplicate_waypoint_order",
                        f"waypoint order {waypoint.order} is already used by "
                        f"waypoints[{first_index[waypoint.order]}]; orders must be unique",
                        waypoint.order,
                    )
                )
            else:
                first_index[waypoint.order] = i
        return problems

    def _initial_bank_problems(self) -> list[FieldProblem]:
        """A given initial bank (the state's, or the method's constant reference bank) must lie
        in the bank range: no trajectory could start outside it."""
        low, high = self.control_limits.bank_lower_deg, self.control_limits.bank_max_deg
        given = [(("initial_state", "bank_deg"), self.initial_state.bank_deg)]
        method_bank = getattr(self.method, "initial_bank_deg", None)
        given.append((("method", "initial_bank_deg"), method_bank))
        return [
            FieldProblem(
                loc,
                "bank_limit",
                f"bank {value:g} deg is outside the bank range [{low:g}, {high:g}] deg of "
                "control_limits",
                value,
            )
            for loc, value in given
            if value is not None and not low <= value <= high
        ]

    def _final_time_problems(self) -> list[FieldProblem]:
        t0 = self.initial_state.time_s
        final = self.final_time
        if isinstance(final, FixedFinalTime) and final.value_s <= t0:
            return [
                FieldProblem(
                    ("final_time", "value_s"),
                    "final_time_order",
                    f"fixed final time ({final.value_s:g} s) must exceed the initial time "
                    f"({t0:g} s)",
                    final.value_s,
                )
            ]
        if isinstance(final, FreeFinalTime) and final.max_s is not None and final.max_s <= t0:
            return [
                FieldProblem(
                    ("final_time", "max_s"),
                    "final_time_order",
                    f"latest final time ({final.max_s:g} s) must exceed the initial time "
                    f"({t0:g} s)",
                    final.max_s,
                )
            ]
        return []

    def _phase_problems(self) -> list[FieldProblem]:
        """With phases, the phases bound the flight: the document-wide final conditions, final
        time and energy interval stay unset, and each phase's own bounds must be usable."""
        if not self.phases:
            return []
        last = len(self.phases) - 1
        problems = [
            FieldProblem(
                ("terminal", name),
                "terminal_with_phases",
                f"with phases, terminal.{name} must be free: give the final conditions as the "
                f"last phase's end (phases[{last}].end.{name})",
            )
            for name, spec in self.terminal.specs().items()
            if not isinstance(spec, FreeSpec)
        ]
        final = self.final_time
        if isinstance(final, FixedFinalTime) or final.max_s is not None:
            loc: tuple[str, ...] = (
                ("final_time",) if isinstance(final, FixedFinalTime) else ("final_time", "max_s")
            )
            problems.append(
                FieldProblem(
                    loc,
                    "final_time_with_phases",
                    "with phases, final_time must be free without max_s: the flight time is the "
                    "sum of the phases' durations, each bounded by its duration_s",
                )
            )
        if self.energy is not None:
            problems.append(
                FieldProblem(
                    ("energy",),
                    "energy_with_phases",
                    "with phases, energy must be left out: phases are flown in time, each "
                    "bounded by its duration_s",
                )
            )
        problems.extend(self._phase_attack_problems())
        problems.extend(self._phase_name_problems())
        problems.extend(self._phase_bank_problems())
        problems.extend(self._phase_thrust_problems())
        return problems

    def _phase_attack_problems(self) -> list[FieldProblem]:
        """Phases optimize the angle of attack: the vehicle's must be an optimized state."""
        attack = self.vehicle.angle_of_attack
        if attack is not None and attack.mode == "optimized":
            return []
        if attack is None:
            reason = (
                "a parabolic polar has none: give polynomial or table aerodynamics with an "
                "optimized angle of attack"
            )
        else:
            reason = (
                f'give {{"mode": "optimized", "min_deg": ..., "max_deg": ...}} instead of '
                f"{attack.mode!r}"
            )
        return [
            FieldProblem(
                ("vehicle", "angle_of_attack"),
                "phases_need_optimized_alpha",
                "with phases, vehicle.angle_of_attack must be optimized (phases optimize the "
                "angle of attack per phase, within each phase's angle_of_attack_deg); " + reason,
            )
        ]

    def _phase_name_problems(self) -> list[FieldProblem]:
        first_index: dict[str, int] = {}
        problems: list[FieldProblem] = []
        for i, phase in enumerate(self.phases):
            if phase.name in first_index:
                problems.append(
                    FieldProblem(
                        ("phases", i, "name"),
                        "duplicate_phase_name",
                        f"phase name {phase.name!r} is already used by "
                        f"phases[{first_index[phase.name]}]; names must be unique",
                        phase.name,
                    )
                )
            else:
                first_index[phase.name] = i
        return problems

    def _phase_bank_problems(self) -> list[FieldProblem]:
        """A phase's bank range, completed by control_limits where it gives no bound, must not be
        empty."""
        limits = self.control_limits
        problems: list[FieldProblem] = []
        for i, phase in enumerate(self.phases):
            given = phase.bank_min_deg is not None, phase.bank_max_deg is not None
            if all(given) or not any(given):  # both: the phase checks them; none: control_limits
                continue
            low, high = phase.bank_range_deg(limits.bank_lower_deg, limits.bank_max_deg)
            if low < high:
                continue
            key = "bank_min_deg" if given[0] else "bank_max_deg"
            other = "control_limits.bank_max_deg" if given[0] else "the control_limits lower bound"
            problems.append(
                FieldProblem(
                    ("phases", i, key),
                    "bank_limit",
                    f"phases[{i}].{key} ({getattr(phase, key):g}) leaves an empty bank range "
                    f"[{low:g}, {high:g}] deg with {other}; give both bank bounds of the phase",
                    getattr(phase, key),
                )
            )
        return problems

    def _phase_thrust_problems(self) -> list[FieldProblem]:
        """A phase's thrust needs an engine, and no more than it gives."""
        engine = self.vehicle.propulsion
        problems: list[FieldProblem] = []
        for i, phase in enumerate(self.phases):
            thrust = phase.thrust_max_n
            if thrust is None or thrust == 0.0:
                continue
            if engine is None:
                problems.append(
                    FieldProblem(
                        ("phases", i, "thrust_max_n"),
                        "thrust_without_propulsion",
                        f"phases[{i}].thrust_max_n ({thrust:g} N) asks for thrust, but the "
                        "vehicle has no propulsion: give vehicle.propulsion, or 0 for a coast",
                        thrust,
                    )
                )
            elif thrust > engine.max_thrust_n:
                problems.append(
                    FieldProblem(
                        ("phases", i, "thrust_max_n"),
                        "thrust_limit",
                        f"phases[{i}].thrust_max_n ({thrust:g} N) exceeds the engine's "
                        f"vehicle.propulsion.max_thrust_n ({engine.max_thrust_n:g} N)",
                        thrust,
                    )
                )
        return problems

    def _propulsion_problems(self) -> list[FieldProblem]:
        """The propellant objective needs an engine that burns propellant."""
        if "min_propellant" not in self.objective.names() or self.vehicle.propulsion is not None:
            return []
        return [
            FieldProblem(
                ("objective",),
                "propellant_without_propulsion",
                "the objective term min_propellant needs vehicle.propulsion: without an engine "
                "no propellant is burnt",
            )
        ]
