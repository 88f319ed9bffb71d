"""The clock of a solve's time limit: CPU seconds of this process, with a wall-clock safety.

A method's ``time_limit_s`` counts the CPU time of the solving process (``time.process_time``:
every thread of the process, the conic solver's and the compiled kernels' included, since all
run in-process), so a solve ends by its iterations, not by the load other processes put on the
machine. A wall-clock limit of ``WALL_FACTOR`` times the CPU limit still ends a solve the
machine starves of CPU. Both clocks are read from callables, so tests can drive them.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

WALL_FACTOR = 4.0
"""The wall-clock safety limit of a solve as a multiple of its CPU-time limit: a solve that gets
a quarter of a core for its whole budget still ends by its CPU limit."""

Clock = Callable[[], float]


@dataclass
class SolveClock:
    """Started once per solve; ``expired`` says which limit ran out, if one did."""

    cpu_limit_s: float
    wall_limit_s: float
    cpu: Clock = time.process_time
    wall: Clock = time.perf_counter
    cpu_start: float = field(default=0.0)
    wall_start: float = field(default=0.0)

    @classmethod
    def start(
        cls,
        cpu_limit_s: float,
        wall_limit_s: float | None = None,
        *,
        cpu: Clock = time.process_time,
        wall: Clock = time.perf_counter,
    ) -> SolveClock:
        """A clock started now; the wall limit defaults to ``WALL_FACTOR`` x the CPU limit."""
        limit = WALL_FACTOR * cpu_limit_s if wall_limit_s is None else wall_limit_s
        return cls(cpu_limit_s, limit, cpu, wall, cpu(), wall())

    def cpu_used_s(self) -> float:
        return self.cpu() - self.cpu_start

    def wall_used_s(self) -> float:
        return self.wall() - self.wall_start

    def remaining_s(self) -> float:
        """The wall seconds left before the safety limit (what a conic solve may take)."""
        return self.wall_limit_s - self.wall_used_s()

    @property
    def wall_deadline(self) -> float:
        """The safety limit as a ``wall`` clock reading."""
        return self.wall_start + self.wall_limit_s

    def expired(self) -> str | None:
        """Which limit has run out, as a message's lead ("CPU time limit 120 s"), or None."""
        if self.cpu_used_s() >= self.cpu_limit_s:
            return f"CPU time limit {self.cpu_limit_s:g} s"
        if self.wall_used_s() >= self.wall_limit_s:
            return (
                f"wall-clock safety limit {self.wall_limit_s:g} s ({WALL_FACTOR:g} x the CPU "
                f"time limit; {self.cpu_used_s():.1f} CPU s used)"
            )
        return None
