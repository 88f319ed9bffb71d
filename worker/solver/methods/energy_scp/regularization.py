"""Per-node weights of the cone-tightness regularization of paper 000 (eq. 22).

The regularization rewards the control along the reference's bank direction, which drives
|u| to 1 (an exact relaxation) but also penalizes turning the bank by about w (1 - cos d): a
weight heavy enough for exactness everywhere holds the bank back wherever the optimum needs it
to turn, and the iterates creep. At the fixed point the reward is normal to the circle, so its
weight does not move the optimum; only where a node falls inside the disc is it needed.
"""

from __future__ import annotations

import numpy as np

from worker.solver.methods.energy_scp.controls import GAP_TOL

Array = np.ndarray
LIGHTEN = 0.5
"""Factor on the weight of a node whose control lay on the circle (and never inside)."""
HEAVIER = 4.0
"""Factor on the weight of a node whose control lay inside the disc (up to the full weight)."""


class ConeRegularization:
    """The regularization weight of each node: the full weight for the first ``hold``
    iterations, then lighter at nodes whose control stays on the circle, down to ``minimum``;
    heavier (up to the full weight) at a node whose control falls inside, which then keeps its
    weight for good."""

    def __init__(self, nodes: int, weight: float, minimum: float, hold: int) -> None:
        self.full = weight
        self.minimum = min(minimum, weight)
        self.hold = hold
        self.weights = np.full(nodes, weight)
        self.needed = np.zeros(nodes, dtype=bool)

    def after_iteration(self, iteration: int, u: Array) -> None:
        """Update from the controls ``u`` (K, 2) of the iteration's subproblem solution."""
        if iteration < self.hold:
            return
        inside = np.linalg.norm(u, axis=1) < 1.0 - GAP_TOL
        self.needed |= inside
        lighter = np.maximum(self.weights * LIGHTEN, self.minimum)
        heavier = np.minimum(self.weights * HEAVIER, self.full)
        self.weights = np.where(inside, heavier, np.where(self.needed, self.weights, lighter))
