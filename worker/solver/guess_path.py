"""A user's initial guess (an earlier answer) as the solver reads it, and its interpolation onto
a method's grid: in time scaled to the new final time, or in energy."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

Array = np.ndarray


@dataclass(frozen=True)
class GuessPath:
    """A trajectory to start from, nondimensional: times from 0 (K,), states [r, theta, phi,
    V, gamma, psi] (K, 6) and bank (K,), radians."""

    t: Array
    y: Array
    bank: Array
    alpha: Array | None = None
    """Angle of attack (K,), radians, when the guess gives one."""

    def on_times(self, t_nodes: Array) -> tuple[Array, Array]:
        """States (N, 6) and bank (N,) at ``t_nodes`` (from 0), the guess's time scaled to
        span the same flight: a guess of another duration is stretched, not cut."""
        scaled = self.t * (float(t_nodes[-1]) / float(self.t[-1]))
        y = np.column_stack([np.interp(t_nodes, scaled, self.y[:, j]) for j in range(6)])
        return y, np.interp(t_nodes, scaled, self.bank)

    def alpha_on_times(self, t_nodes: Array) -> Array | None:
        """The guess's angle of attack at ``t_nodes`` (scaled as :meth:`on_times`), or None."""
        if self.alpha is None:
            return None
        scaled = self.t * (float(t_nodes[-1]) / float(self.t[-1]))
        return np.interp(t_nodes, scaled, self.alpha)

    def energy(self) -> Array:
        """Energy e = 1/r - V^2/2 at each point (paper 000 eq. 7), made non-decreasing (a
        flight's energy only falls; round-off wiggles are flattened)."""
        e = 1.0 / self.y[:, 0] - 0.5 * self.y[:, 3] ** 2
        return np.asarray(np.maximum.accumulate(e))

    def on_energies(self, e_nodes: Array) -> tuple[Array, Array]:
        """States (N, 6) and bank (N,) at energies ``e_nodes``, the guess's energy range mapped
        onto theirs (its first point to the first node, its last to the last)."""
        e = self.energy()
        scaled = e_nodes[0] + (e - e[0]) * ((e_nodes[-1] - e_nodes[0]) / (e[-1] - e[0]))
        keep = np.concatenate([[True], np.diff(scaled) > 0])  # strictly increasing for interp
        y = np.column_stack([np.interp(e_nodes, scaled[keep], self.y[keep, j]) for j in range(6)])
        return y, np.interp(e_nodes, scaled[keep], self.bank[keep])
