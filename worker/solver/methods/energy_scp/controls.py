"""The bank profile's checks and repair in paper 000's relaxation u = (cos sigma, sin sigma),
|u| <= 1 (eq. 20-22): node-to-node chatter, and controls left inside the disc."""

from __future__ import annotations

import numpy as np

Array = np.ndarray
GAP_TOL = 1e-3
"""A control with |u| below 1 - GAP_TOL is off the circle: the relaxation is not exact there,
and a step is not called converged."""


def bank_chatter(u: Array, angle_deg: float) -> int:
    """Nodes where the bank zigzags: the bank steps before and after alternate in sign with
    the next one too, each larger than ``angle_deg`` (a node-to-node chatter that the trapezoid
    averages into lift the vehicle cannot fly; a smooth reversal turns one way)."""
    step = np.degrees(np.diff(np.unwrap(np.arctan2(u[:, 1], u[:, 0]))))
    big = np.abs(step) > angle_deg
    flip = step[:-1] * step[1:] < 0
    zig = flip[:-1] & flip[1:] & big[:-2] & big[1:-1] & big[2:]
    return int(np.count_nonzero(zig))


def lift_preserving(u: Array, u_ref: Array) -> Array:
    """Controls inside the disc |u| < 1 moved onto the circle with the same u1 = cos(sigma): the
    bank that flies the same vertical lift, turned to the side of u2 (of the reference when u2
    is zero). The relaxation (paper 000 eq. 22) is exact only on the circle; the next reference
    (and the regularization's direction) then carries a bank the vehicle can fly."""
    norm = np.linalg.norm(u, axis=1)
    inside = norm < 1.0 - GAP_TOL
    if not np.any(inside):
        return u
    side = np.where(u[:, 1] != 0.0, np.sign(u[:, 1]), np.where(u_ref[:, 1] < 0.0, -1.0, 1.0))
    u1 = np.clip(u[:, 0], -1.0, 1.0)
    out = u.copy()
    out[inside, 0] = u1[inside]
    out[inside, 1] = side[inside] * np.sqrt(1.0 - u1[inside] ** 2)
    return out
