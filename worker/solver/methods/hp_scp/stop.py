"""hp-scp's stop test on an accepted step: a small step, or an objective that has settled, is
converged once the trust penalty no longer shapes it; until then the weight is lightened and
the run goes on (a probe)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class SettledProbe:
    """Whether a settled objective has already led to a lighter probe on the current mesh:
    settled again after it (the lighter steps rejected, or going nowhere), the reference is
    stationary on this mesh whatever the weight."""

    probed: bool = False

    def reset(self) -> None:
        """A new mesh (or a new stage): the settling starts again."""
        self.probed = False

    def judge(
        self, small_step: bool, settled: bool, defects_met: bool, can_lighten: bool
    ) -> tuple[bool, bool]:
        """(converged, probe) for an accepted step: small (a small step or a settled objective,
        with the defects met) is converged unless the weight can still be lightened and this is
        not a settling already probed; then it is a probe (lighten and go on)."""
        small = (small_step or settled) and defects_met
        if small and can_lighten and not (settled and self.probed):
            self.probed = self.probed or settled
            return False, True
        return small, False
