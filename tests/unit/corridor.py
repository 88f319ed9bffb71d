"""Random point-mass states over the entry corridor, for the Jacobian tests of every model."""

from __future__ import annotations

import numpy as np


def corridor_states(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` time-form states [r, theta, phi, V, gamma, psi] (nondimensional, Earth radius) from
    20 to 100 km, speeds on both sides of the alpha schedule's break."""
    return np.column_stack(
        [
            1.0 + rng.uniform(20e3, 100e3, n) / 6378140.0,
            rng.uniform(-1.0, 1.0, n),
            rng.uniform(-1.2, 1.2, n),
            rng.uniform(0.15, 0.95, n),
            rng.uniform(-0.3, 0.1, n),
            rng.uniform(-3.0, 3.0, n),
        ]
    )
