"""The time limit counts the solving process's CPU time, with a wall-clock safety of 4 x it.

The logic on driven clocks: the CPU limit ends a run, a wall clock running ahead (a loaded
machine) does not, until the safety limit. Then one real solve, pinned to one core beside two
busy loops (it gets at most a third of the core): it ends by its iteration budget within a time
limit that its wall-clock time on that core exceeds, where a wall-clock limit ended it
``timed_out``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from typing import Any

import numpy as np
import pytest

from tests.unit.test_honest_status import _Backend, _Steps
from worker.solver.scp.loop import Budget, run_scp
from worker.solver.solve_clock import WALL_FACTOR, SolveClock


class _Clocks:
    """A CPU and a wall clock that tests move by hand."""

    def __init__(self) -> None:
        self.cpu_s = 0.0
        self.wall_s = 0.0

    def clock(self, limit_s: float) -> SolveClock:
        return SolveClock.start(limit_s, cpu=lambda: self.cpu_s, wall=lambda: self.wall_s)


def test_the_cpu_limit_expires_by_cpu_time_and_the_safety_by_wall_time() -> None:
    clocks = _Clocks()
    clock = clocks.clock(10.0)
    assert clock.wall_limit_s == WALL_FACTOR * 10.0
    clocks.cpu_s, clocks.wall_s = 9.9, 39.0  # a machine four times over-subscribed
    assert clock.expired() is None
    assert clock.remaining_s() == pytest.approx(1.0)  # what a conic solve may take, wall
    clocks.cpu_s = 10.0
    assert clock.expired() == "CPU time limit 10 s"
    clocks.cpu_s, clocks.wall_s = 2.0, 40.0  # starved: the safety ends it
    assert (clock.expired() or "").startswith("wall-clock safety limit 40 s")


class _Burning(_Steps):
    """The driver's fake method, each iteration costing 1 s of CPU and ``wall_s`` of wall."""

    def __init__(self, clocks: _Clocks, wall_s: float) -> None:
        super().__init__([1.0] * 50)
        self.clocks, self.wall_s = clocks, wall_s

    def linearize(self, reference: np.ndarray) -> None:
        self.clocks.cpu_s += 1.0
        self.clocks.wall_s += self.wall_s


@pytest.mark.parametrize(
    ("wall_per_cpu", "max_iterations", "status", "iterations", "message"),
    [
        (3.0, 5, "max_iterations", 5, "not converged in 5 iterations"),
        (1.0, 50, "timed_out", 5, "CPU time limit 4.5 s reached after 5 iterations"),
        (10.0, 50, "timed_out", 2, "wall-clock safety limit 18 s"),
    ],
)
def test_the_driver_ends_by_iterations_however_loaded_until_the_safety(
    wall_per_cpu: float, max_iterations: int, status: str, iterations: int, message: str
) -> None:
    """Iterations of 1 CPU s each against a 4.5 s limit (safety 18 s). Five of them at 3 wall
    s per CPU s take 15 s of wall-clock time, which a wall-clock limit of 4.5 s would have cut
    after two: they end by their budget. Unloaded, the fifth iteration passes the limit; at 10
    wall s per CPU s the safety ends the run after two."""
    clocks = _Clocks()
    outcome = run_scp(
        _Burning(clocks, wall_per_cpu),
        Budget(max_iterations, 4.5),
        _Backend(),
        clock=clocks.clock(4.5),
    )
    assert (outcome.status, len(outcome.history)) == (status, iterations)
    assert (outcome.failure_message or "").startswith(message)


CHILD = textwrap.dedent(
    """
    import copy, json, os, sys, time
    os.sched_setaffinity(0, {{{cpu}}})
    from app.schemas import ProblemDocument
    from worker.solver.api import solve_problem
    from worker.solver.scenarios import get_scenario
    doc = copy.deepcopy(get_scenario("rlv-min-heat-load").problem)
    doc["method"].update(max_iterations=8, time_limit_s=3600)
    solve_problem(ProblemDocument.model_validate(doc))  # the kernels loaded
    start = time.process_time()
    solve_problem(ProblemDocument.model_validate(doc))  # alone: what the solve costs
    cost = time.process_time() - start
    print(json.dumps({{"ready": cost}}), flush=True)
    sys.stdin.readline()  # the busy loops have started
    doc["method"]["time_limit_s"] = 1.5 * cost
    wall = time.perf_counter()
    result = solve_problem(ProblemDocument.model_validate(doc))
    wall = time.perf_counter() - wall
    print(json.dumps({{"status": result["status"], "code": result["failure"]["code"],
                      "iterations": len(result["history"]), "limit": 1.5 * cost,
                      "wall": wall}}), flush=True)
    """
)


@pytest.mark.slow
@pytest.mark.exclusive
def test_a_solve_beside_busy_processes_ends_by_iterations_not_by_the_clock() -> None:
    """Alone on its core, 8 energy-scp iterations of paper 000's case cost C CPU s (their
    verification and set-up included). Beside two busy loops on that core they take at least
    3 x their CPU time of wall-clock time, more than the 1.5 C limit: a wall-clock limit ends
    them ``timed_out``; the CPU-time limit lets them end by their iteration budget (failed,
    max_iterations)."""
    cpu = max(os.sched_getaffinity(0))
    env = {**os.environ, "PYTHONPATH": os.getcwd()}
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD.format(cpu=cpu)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    busy: list[subprocess.Popen[str]] = []
    try:
        assert child.stdout is not None and child.stdin is not None
        json.loads(child.stdout.readline())
        loop = (
            f"import os\nos.sched_setaffinity(0, {{{cpu}}})\nprint('spinning', flush=True)\n"
            "while True:\n    pass\n"
        )
        busy = [
            subprocess.Popen([sys.executable, "-c", loop], stdout=subprocess.PIPE, text=True)
            for _ in range(2)
        ]
        for process in busy:  # both loops on the core before the solve starts
            assert process.stdout is not None and process.stdout.readline() == "spinning\n"
        child.stdin.write("go\n")
        child.stdin.flush()
        line = child.stdout.readline()
        assert line, "the solving process ended without a result"
        result: dict[str, Any] = json.loads(line)
    finally:
        for process in busy:
            process.kill()
            process.wait()
        child.kill()
        child.wait()
    # the whole solve's wall-clock time, as the C it is compared with: a wall-clock limit
    # would have ended it
    assert result["wall"] > result["limit"], result
    assert (result["status"], result["code"], result["iterations"]) == (
        "failed",
        "max_iterations",
        8,
    ), result
