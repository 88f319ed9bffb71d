"""A non-monotone filter for a line search on an SCP step (paper 003 sec. 4.3, step 2.2, after
Fletcher & Leyffer's filter): a trial point is judged by its constraint violation c and its
objective f, never by a merit function that would need a penalty weight.

A trial (c, f) is acceptable when no filter entry dominates it and it improves on the recent
history: c <= (1 - zeta_c) c_q or f <= f_q - zeta_f c, with c_q and f_q the largest violation and
objective of the last M and M_hat accepted points (the non-monotone reference values of paper 003
eq. 74: the objective may rise for a while as long as the trend is down). On acceptance the filter
takes the envelope of the accepted point (eq. 75) and the history moves on.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field


@dataclass
class NonMonotoneFilter:
    """The filter set and the non-monotone memory of accepted points."""

    c_max: float = float("inf")
    """Largest admissible violation (the initial filter F_0 = {c >= c_max})."""
    zeta_c: float = 1.0e-4
    zeta_f: float = 1.0e-4
    memory: int = 4
    """M = M_hat: how many accepted points the reference values look back over."""
    entries: list[tuple[float, float]] = field(default_factory=list)
    history: deque[tuple[float, float]] = field(default_factory=deque)

    def _references(self) -> tuple[float, float] | None:
        if not self.history:
            return None
        return max(c for c, _ in self.history), max(f for _, f in self.history)

    def dominated(self, c: float, f: float) -> bool:
        """Whether (c, f) lies in the filter (some entry is at least as good in both, with the
        margins), or beyond the admissible violation."""
        if c >= self.c_max:
            return True
        return any(c >= ce and f >= fe for ce, fe in self.entries)

    def acceptable(self, c: float, f: float) -> bool:
        """Paper 003 eq. 74: not in the filter, and a sufficient decrease of the violation or of
        the objective against the non-monotone references (always, for the first point)."""
        if self.dominated(c, f):
            return False
        refs = self._references()
        if refs is None:
            return True
        c_q, f_q = refs
        return c <= (1.0 - self.zeta_c) * c_q or f <= f_q - self.zeta_f * c

    def accept(self, c: float, f: float) -> None:
        """Record an accepted point: the filter takes its envelope (eq. 75, entries that it
        dominates dropped) and the memory moves on."""
        refs = self._references()
        if refs is not None:
            c_q, f_q = refs
            entry = ((1.0 - self.zeta_c) * c_q, f_q - self.zeta_f * c)
            self.entries = [
                e for e in self.entries if not (e[0] >= entry[0] and e[1] >= entry[1])
            ] + [entry]
        self.history.append((c, f))
        while len(self.history) > self.memory:
            self.history.popleft()

    def start(self, c: float, f: float) -> None:
        """The first (reference) point: remembered, not filtered."""
        self.history.clear()
        self.history.append((c, f))
