"""Paper 004's evolutionary collocation as a method: the guess (global search or constant
controls), the SQP on the LGL collocation NLP, and the answer as a phased trajectory.

The history holds one record per generation of the global search (``extra.stage``
"global_guess": its best score) and one per SQP iteration (``extra.stage`` "sqp": step length,
penalty, trust box, violations). A run that cannot meet its conditions ends ``failed`` with
the conditions it misses at its last point, by how much, in SI units.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from app.schemas.methods import LglSqpOptions
from worker.solver.conic import make_backend
from worker.solver.global_search import SearchBudget, search_seconds
from worker.solver.methods.base import MethodResult
from worker.solver.methods.lgl_sqp.guess import Guess, global_guess, guess_on_mesh
from worker.solver.methods.lgl_sqp.nlp import PhasedNlp
from worker.solver.methods.lgl_sqp.sqp import SqpIteration, SqpOutcome, SqpSettings, solve_sqp
from worker.solver.models.powered import path_ratios
from worker.solver.phase_search import Parameterization, constant_params
from worker.solver.phased_problem import PhasedProblem
from worker.solver.scp.history import IterationRecord
from worker.solver.scp.loop import IterationSink, StopCheck
from worker.solver.solve_clock import SolveClock
from worker.solver.trajectory import TIME_STATE_NAMES, PhasedTrajectory
from worker.solver.transcription.lgl import LglMesh

Array = np.ndarray
UNMET_LIMIT = 6
"""How many unmet conditions a failure message names."""
SWITCH_SHARE = 0.01
"""A segment whose commanded thrust changes by more than this share of the phase's largest
thrust holds a burn's start or end."""
SWITCH_SPLIT = 8
"""Parts a segment holding a switch is cut into by the refinement (the others: 2)."""
REFINEMENT_FALLBACK = ("max_iterations", "failed", "infeasible")
"""Ends of the refinement stage after which the first mesh's converged answer is reported
(a cancelled or timed-out refinement ends the run as such)."""
PATH_OVERSHOOT = 2e-3
"""A segment whose interpolants exceed a path limit by more than this share between its points
is halved by the path refinement (the verification flies the same interpolants: on a Shuttle
problem their peak was 1.0187 of the heat-rate limit where the flight's was 1.0176)."""
PATH_SAMPLES = 16
"""Samples per segment at which the path refinement evaluates the limits."""
PATH_ROUNDS = 3
"""Most path-refinement rounds: a segment is cut into at most 2**PATH_ROUNDS."""
SI_TOLERANCE = {
    "altitude_m": 1.0,
    "longitude_deg": 1e-4,
    "latitude_deg": 1e-4,
    "velocity_m_s": 0.1,
    "flight_path_angle_deg": 1e-4,
    "heading_deg": 1e-4,
}
"""Misses below these (m, deg, m/s) are not named as unmet by a failure message."""


@dataclass
class LglControls:
    """The controls as the method represents them: the degree-n interpolant of each segment's
    point values, clipped to the phase's bounds."""

    meshes: list[LglMesh]
    values: list[Array]
    starts: list[float]
    durations: list[float]
    lower: list[Array]
    upper: list[Array]

    def at(self, phase: int, t: Array) -> Array:
        s = (np.asarray(t, dtype=float) - self.starts[phase]) / self.durations[phase]
        u = self.meshes[phase].at(self.values[phase], np.clip(s, 0.0, 1.0))
        return np.clip(u, self.lower[phase], self.upper[phase])

    def breaks(self, phase: int) -> Array:
        return self.starts[phase] + self.durations[phase] * self.meshes[phase].breaks


def _burn_meshes(
    problem: PhasedProblem, options: LglSqpOptions, nlp: PhasedNlp, z: Array
) -> list[LglMesh] | None:
    """The meshes of the refinement stage from the answer ``z`` on ``nlp``: each phase that may
    thrust on twice its segments, a segment over which the commanded thrust changes (a burn's
    start or end) on SWITCH_SPLIT; None when no phase may thrust, the user gave phase_nodes, or
    refinement is off."""
    if not options.refine_burns or options.phase_nodes is not None:
        return None
    if not any(ph.thrust_max > 0 for ph in problem.phases):
        return None
    meshes = []
    for p, (mesh, ph) in enumerate(zip(nlp.meshes, problem.phases, strict=True)):
        if ph.thrust_max <= 0:
            meshes.append(mesh)
            continue
        command = nlp.controls(z, p)[:, 2]
        breaks: list[float] = []
        for k in range(mesh.segments):
            values = command[mesh.segment_slice(k)]
            switches = values.max() - values.min() > SWITCH_SHARE * ph.thrust_max
            parts = SWITCH_SPLIT if switches else 2
            breaks.extend(np.linspace(mesh.breaks[k], mesh.breaks[k + 1], parts + 1)[:-1])
        meshes.append(LglMesh(np.array([*breaks, 1.0]), mesh.degree))
    return meshes


def _path_meshes(
    problem: PhasedProblem, options: LglSqpOptions, nlp: PhasedNlp, z: Array
) -> tuple[list[LglMesh], int, float] | None:
    """The meshes of a path-refinement round from the answer ``z``: each segment whose
    interpolated states and controls exceed a path limit by more than ``PATH_OVERSHOOT``
    between its points halved (hp-adaptive refinement on the constraint's error, after Darby,
    Hager & Rao 2011); with the segments halved and the largest ratio found, or None when no
    segment overshoots, the user gave phase_nodes, or refinement is off."""
    if not options.refine_path_limits or options.phase_nodes is not None:
        return None
    local = np.linspace(0.0, 1.0, PATH_SAMPLES + 1)
    meshes, halved, worst = [], 0, 0.0
    for p, (mesh, ph) in enumerate(zip(nlp.meshes, problem.phases, strict=True)):
        x, u = nlp.states(z, p), nlp.controls(z, p)
        u0 = nlp.slots[p].u0
        lower, upper = nlp.lower[u0 : u0 + nlp.nu], nlp.upper[u0 : u0 + nlp.nu]
        breaks: list[float] = []
        for k in range(mesh.segments):
            a, b = mesh.breaks[k], mesh.breaks[k + 1]
            s = a + (b - a) * local
            uk = np.clip(mesh.at(u, s), lower, upper)
            ratios = path_ratios(nlp.model, ph.limits, mesh.at(x, s), uk)
            peak = float(ratios.max()) if ratios.size else 0.0
            worst = max(worst, peak)
            over = peak > 1.0 + PATH_OVERSHOOT
            halved += over
            breaks.extend([a, 0.5 * (a + b)] if over else [a])
        meshes.append(LglMesh(np.array([*breaks, 1.0]), mesh.degree))
    return (meshes, halved, worst) if halved else None


def _on_mesh(coarse: PhasedNlp, fine: PhasedNlp, z: Array) -> Array:
    """The point ``z`` of ``coarse`` carried onto ``fine``'s mesh by each segment's LGL
    interpolant (durations kept)."""
    xs, us, taus = [], [], []
    for p, (a, b) in enumerate(zip(coarse.slots, fine.slots, strict=True)):
        xs.append(a.mesh.at(coarse.states(z, p), b.mesh.s))
        us.append(a.mesh.at(coarse.controls(z, p), b.mesh.s))
        taus.append(coarse.duration(z, p))
    return fine.pack(xs, us, taus)


def _meshes(problem: PhasedProblem, options: LglSqpOptions) -> list[LglMesh]:
    counts = options.phase_nodes or [options.nodes] * len(problem.phases)
    if len(counts) != len(problem.phases):
        raise ValueError(
            f"method.phase_nodes gives {len(counts)} phases, the problem has {len(problem.phases)}"
        )
    return [LglMesh.uniform((n - 1) // options.degree, options.degree) for n in counts]


def trajectory_of(nlp: PhasedNlp, z: Array) -> PhasedTrajectory:
    """The phased trajectory of the NLP point ``z``."""
    ts, xs, us, phase, bounds = [], [], [], [], []
    starts, durations, values, lows, highs = [], [], [], [], []
    t0 = 0.0
    for p, slot in enumerate(nlp.slots):
        tau = nlp.duration(z, p)
        ts.append(t0 + tau * slot.mesh.s)
        xs.append(nlp.states(z, p))
        u = nlp.controls(z, p)
        us.append(u)
        phase.append(np.full(slot.mesh.points, p))
        bounds.append((t0, t0 + tau))
        starts.append(t0)
        durations.append(tau)
        values.append(u.copy())
        lows.append(nlp.lower[slot.u0 : slot.u0 + nlp.nu])
        highs.append(nlp.upper[slot.u0 : slot.u0 + nlp.nu])
        t0 += tau
    controls = LglControls(nlp.meshes, values, starts, durations, lows, highs)
    return PhasedTrajectory(
        t=np.concatenate(ts),
        x=np.concatenate(xs),
        u=np.concatenate(us),
        phase=np.concatenate(phase),
        bounds=bounds,
        controls=controls,
    )


def _to_si(nlp: PhasedNlp, i: int, value: float) -> float:
    sc = nlp.problem.base.scales
    if i == 0:
        return (value - 1.0) * sc.radius_m
    if i == 3:
        return value * sc.speed_m_s
    return math.degrees(value)


def over_limit(excess: float) -> str:
    """A path value ``excess`` (a share of the limit) above its limit, in digits that show it
    is over: 1.2e-06 reads "0.00012 % over its limit", not "1.0000 of its limit"."""
    percent = 100.0 * excess
    shown = f"{percent:.0f}" if percent >= 100.0 else f"{percent:.2g}"
    return f"{shown} % over its limit"


def sqp_failure_lead(
    out: SqpOutcome, options: LglSqpOptions, history: int, generations: int, refined: int
) -> str:
    """How an SQP that did not converge ended, its iterations counted as the history's records
    are (``history`` records in all, the first ``generations`` of them the global search's, the
    last ``refined`` on the refined mesh), so the message and ``timing.iterations`` agree."""
    sqp = history - generations
    if out.status == "max_iterations":
        lead = f"not converged in {options.max_iterations} SQP iterations"
        if sqp < options.max_iterations:
            failed = options.max_iterations - sqp
            lead += f" ({failed} of them a failed QP, which leaves no record)"
    elif out.status == "timed_out":
        limit = (out.message or "").partition(" reached")[0]
        limit = limit or f"CPU time limit {options.time_limit_s:g} s"
        lead = f"{limit} reached after {sqp} SQP iterations"
    elif out.status == "cancelled":
        lead = f"cancelled after {sqp} SQP iterations"
    else:
        lead = out.message or f"the SQP ended {out.status} after {sqp} iterations"
    where = [f"history records {generations + 1}-{history}" if sqp else "no SQP record"]
    if refined:
        where[0] += f", the last {refined} on the refined mesh"
    if generations:
        algorithm = options.global_guess.algorithm.upper()
        where.append(f"records 1-{generations} are the {algorithm} search's generations")
    return f"{lead} ({'; '.join(where)})"


def unmet_conditions(nlp: PhasedNlp, z: Array) -> list[str]:
    """The phase end conditions and path limits the point ``z`` misses, worst first, in SI."""
    found: list[tuple[float, str]] = []
    for p, ph in enumerate(nlp.problem.phases):
        end = nlp.states(z, p)[-1]
        for i, name in enumerate(TIME_STATE_NAMES):
            spec = ph.end_si[name]
            value = _to_si(nlp, i, float(end[i]))
            if spec.kind == "fixed":
                assert spec.value is not None
                miss, what = value - spec.value, f"fixed at {spec.value:g}"
            elif spec.kind == "range":
                assert spec.lo is not None and spec.hi is not None
                if value > spec.hi:
                    miss, what = value - spec.hi, f"above its upper bound {spec.hi:g}"
                elif value < spec.lo:
                    miss, what = spec.lo - value, f"below its lower bound {spec.lo:g}"
                else:
                    continue
            else:
                continue
            if abs(miss) > SI_TOLERANCE[name]:
                found.append(
                    (
                        abs(miss) / SI_TOLERANCE[name],
                        f"phase {ph.name!r} ends with {name} = {value:.6g}, {what} "
                        f"(off by {abs(miss):.4g})",
                    )
                )
    ev = nlp.evaluate(z)
    kinds = nlp.ineq_info
    for k, kind in enumerate(kinds.kind):
        if kind == "path" and ev.ineq[k] > 1e-6:
            p, point, name = kinds.phase[k], kinds.point[k], kinds.name[k]
            found.append(
                (
                    ev.ineq[k] * 1e4,
                    f"phase {nlp.problem.phases[p].name!r}: {name} {over_limit(ev.ineq[k])} at "
                    f"point {point}",
                )
            )
    dyn = float(np.max(np.abs(ev.eq[[k != "end" for k in nlp.eq_info.kind]]), initial=0.0))
    if dyn > 1e-6:
        found.append((0.0, f"the dynamics are not met (largest scaled defect {dyn:.3g})"))
    found.sort(key=lambda item: -item[0])
    return [text for _, text in found]


def _sqp_record(
    nlp: PhasedNlp, it: SqpIteration, prev: Array | None, offset: int
) -> IterationRecord:
    terms = nlp.objective_terms(it.z)
    change: dict[str, float] = {}
    if prev is not None:
        sc = nlp.problem.base.scales
        unit = (sc.radius_m, math.degrees(1.0), math.degrees(1.0), sc.speed_m_s,
                math.degrees(1.0), math.degrees(1.0))  # fmt: skip
        for i, name in enumerate(TIME_STATE_NAMES):
            delta = max(
                float(np.max(np.abs(nlp.states(it.z, p)[:, i] - nlp.states(prev, p)[:, i])))
                for p in range(len(nlp.slots))
            )
            change[name] = delta * unit[i]
    single = next(iter(terms.values())) if len(terms) == 1 else it.objective
    return IterationRecord(
        iteration=it.iteration + offset,
        cost=float(single),
        cost_terms={f"objective:{k}": v for k, v in terms.items()},
        objective_value=float(single),
        max_state_change=change,
        trust_region_slack=it.squared_step,
        virtual_control_norm=it.elastic,
        linearization_error=it.largest_defect,
        nodes_post_corrected=None,
        relaxation_gap=None,
        conic_status=it.qp_status,
        conic_solver="clarabel",
        conic_solve_s=it.qp_solve_s,
        conic_setup_s=it.qp_setup_s,
        iteration_wall_s=it.wall_s,
        subproblem_cost=it.merit,
        extra={
            "stage": "sqp",
            "step_length": it.step_length,
            "step": it.step,
            "penalty": it.penalty,
            "trust_box": it.trust,
            "accepted": it.accepted,
            "violation_dynamics": it.violation_dynamics,
            "violation_conditions": it.violation_conditions,
            "max_violation": it.max_violation,
            "line_search": it.line_search,
            "qp_iterations": it.qp_iterations,
            "largest_step_at": it.largest_step_at,
        },
    )


def _guess_record(generation: int, best: float, algorithm: str, wall: float) -> IterationRecord:
    return IterationRecord(
        iteration=generation,
        cost=float(best),
        cost_terms={},
        objective_value=None,
        max_state_change={},
        trust_region_slack=0.0,
        virtual_control_norm=0.0,
        linearization_error=0.0,
        nodes_post_corrected=None,
        relaxation_gap=None,
        conic_status="not_used",
        conic_solver="none",
        conic_solve_s=0.0,
        conic_setup_s=0.0,
        iteration_wall_s=wall,
        extra={
            "stage": "global_guess",
            "generation": generation,
            "best_score": float(best),
            "algorithm": algorithm,
        },
    )


def run(
    problem: PhasedProblem,
    options: LglSqpOptions,
    on_iteration: IterationSink | None = None,
    should_stop: StopCheck | None = None,
) -> MethodResult:
    """Guess, then SQP; the answer and its history."""
    clock = SolveClock.start(options.time_limit_s)
    nlp = PhasedNlp(problem, _meshes(problem, options))
    par = Parameterization(problem, options.global_guess.knots)
    history: list[IterationRecord] = []

    def emit(record: IterationRecord) -> None:
        history.append(record)
        if on_iteration is not None:
            on_iteration(record)

    extra: dict[str, Any] = {}
    guess: Guess
    if options.initial_guess == "global":
        gg = options.global_guess
        last = [time.perf_counter()]

        def progress(generation: int, best: float) -> None:
            now = time.perf_counter()
            emit(_guess_record(generation, best, gg.algorithm, now - last[0]))
            last[0] = now
            if should_stop is not None and should_stop():
                raise _StoppedError

        try:
            guess = global_guess(
                par,
                nlp,
                algorithm=gg.algorithm,
                seed=gg.seed,
                population=gg.population,
                budget=SearchBudget(
                    gg.max_evaluations, search_seconds(gg.time_limit_s, options.time_limit_s)
                ),
                progress=progress,
            )
        except _StoppedError:
            return MethodResult(
                status="cancelled",
                trajectory=None,
                history=history,
                conic_solve_s=0.0,
                failure_code="cancelled",
                failure_message="cancelled during the global search",
            )
        assert guess.search is not None
        s = guess.search
        extra["global_guess"] = {
            "algorithm": s.algorithm,
            "seed": s.seed,
            "population": s.population,
            "generations": s.generations,
            "evaluations": s.evaluations,
            "best_score": s.score,
            "wall_s": s.wall_s,
            "stopped_by": s.stopped_by,
        }
    else:
        guess = guess_on_mesh(par, nlp, constant_params(par))
        extra["constant_guess"] = {"score": guess.score}
    stage = _Stage(nlp, len(history), 1)

    def on_sqp(it: SqpIteration, _ev: Any) -> None:
        record = _sqp_record(stage.nlp, it, stage.previous, stage.offset)
        record.extra["mesh"] = stage.mesh
        emit(record)
        stage.previous = it.z

    settings = SqpSettings(
        max_iterations=options.max_iterations,
        time_limit_s=options.time_limit_s,
        feasibility_tolerance=options.feasibility_tolerance,
        step_tolerance=options.step_tolerance,
        line_search=options.line_search,
        conic_time_limit_s=options.conic_time_limit_s,
    )
    backend = make_backend(options.conic_backend, fallback=options.fallback_solver)
    z0 = nlp.pack(guess.states, guess.controls, guess.durations)
    generations = len(history)
    out = solve_sqp(
        nlp, z0, settings, backend, on_iteration=on_sqp, should_stop=should_stop,
        clock=clock, offset=generations,
    )  # fmt: skip
    refined_records = 0
    extra["sqp"] = {
        "status": out.status,
        "iterations": len(out.iterations),
        "qp_solve_s": out.qp_solve_s,
    }

    def resolve(meshes: list[LglMesh]) -> tuple[SqpOutcome, PhasedNlp, bool]:
        """The SQP again on ``meshes`` from the current answer, within what is left of the
        budget, and whether its answer replaces the current one."""
        nonlocal stage
        refined = PhasedNlp(problem, meshes)
        stage = _Stage(refined, len(history), stage.mesh + 1)
        budget = max(options.max_iterations - (len(history) - generations), 1)
        second = solve_sqp(
            refined, _on_mesh(nlp, refined, out.z), replace(settings, max_iterations=budget),
            backend, on_iteration=on_sqp, should_stop=should_stop, clock=clock,
            offset=stage.offset,
        )  # fmt: skip
        second.qp_solve_s += out.qp_solve_s
        return second, refined, second.status not in REFINEMENT_FALLBACK

    fine = _burn_meshes(problem, options, nlp, out.z) if out.status == "converged" else None
    if fine is not None:
        # the burn's switches resolved: the thrusting phases again on twice their segments,
        # from the first answer, within what is left of the budget
        second, refined, kept = resolve(fine)
        extra["sqp"]["refined"] = {
            "status": second.status,
            "iterations": len(second.iterations),
            "nodes": [m.points for m in fine],
            "answer": "refined mesh" if kept else "first mesh (the refinement did not converge)",
        }
        if kept:
            out, nlp = second, refined
            refined_records = len(history) - stage.offset
        else:
            out.qp_solve_s = second.qp_solve_s
    rounds: list[dict[str, Any]] = []
    while out.status == "converged" and len(rounds) < PATH_ROUNDS:
        found = _path_meshes(problem, options, nlp, out.z)
        if found is None:
            break
        # a limit exceeded between the points: the overshooting segments halved, from the
        # answer, within what is left of the budget
        meshes, halved, worst = found
        second, refined, kept = resolve(meshes)
        rounds.append(
            {
                "peak_ratio_between_points": worst,
                "segments_halved": halved,
                "status": second.status,
                "iterations": len(second.iterations),
                "nodes": [m.points for m in meshes],
            }
        )
        if not kept:
            out.qp_solve_s = second.qp_solve_s
            break
        out, nlp = second, refined
        refined_records = len(history) - stage.offset
    if rounds:
        extra["sqp"]["path_refinement"] = rounds
    status: Any = out.status
    code = message = None
    if out.status == "infeasible":
        status, code = "failed", "infeasible"
    elif out.status == "failed":
        code = "numerical_error"
    elif out.status == "max_iterations":
        code = "max_iterations"
    elif out.status in ("timed_out", "cancelled"):
        code = out.status
    if status != "converged":
        unmet = unmet_conditions(nlp, out.z)
        lead = sqp_failure_lead(out, options, len(history), generations, refined_records)
        tail = "; unmet: " + "; ".join(unmet[:UNMET_LIMIT]) if unmet else ""
        message = lead + tail
    return MethodResult(
        status=status,
        trajectory=trajectory_of(nlp, out.z),
        history=history,
        conic_solve_s=out.qp_solve_s,
        objective_terms=nlp.objective_terms(out.z),
        failure_code=code,
        failure_message=message,
        extra=extra,
    )


@dataclass
class _Stage:
    """The mesh the SQP iterates on (1: the user's, 2: the burns refined, then one more per
    path-refinement round), where its records start in the history, and its last point (for the
    records' state changes)."""

    nlp: PhasedNlp
    offset: int
    mesh: int
    previous: Array | None = None


class _StoppedError(Exception):
    """The caller asked to stop during the global search."""
