"""Inverse-free exact first-order-hold discretization of the bank-state dynamics (paper 002).

On interval k, with tau in [0, 1], FOH control w(tau) = (1 - tau) w_k + tau w_{k+1} and interval
length s_k, the reference x(tau) from x(0) = z_k obeys dx/dtau = s_k f(x, w) (eq. 10); the
deviation dynamics are discretized exactly (eq. 17-24) by integrating alongside it

    dPhi/dtau = A Phi,               Phi(0) = I,
    dB-/dtau  = A B- + (1 - tau) B,  B-(0) = 0,
    dB+/dtau  = A B+ + tau B,        B+(0) = 0,
    dS/dtau   = A S + f,             S(0) = 0,

the inverse-free form of Theorem 1 (eq. 19), so no STM inverse is formed. The (N, 7, 11) system
[x | Phi | B- | B+ | S] advances by classical Runge-Kutta steps: in a compiled loop over the
intervals (``models.bank_state_sweeps``) when the force models have a compiled form, else vectorized
over all intervals at once in numpy. The result gives the stitched subproblem
dynamics dz_{k+1} = Phi_k dz_k + B-_k dw_k + B+_k dw_{k+1} + S_k ds_k + (x_prop_{k+1} - z_{k+1}).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from worker.solver.forces import VehicleForces
from worker.solver.models.bank_state import bank_state_dynamics
from worker.solver.models.bank_state_compiled import (
    compiled_parameters,
    float_arrays,
    propagate_kernel,
)
from worker.solver.models.bank_state_sweeps import interval_maps_kernel

Array = np.ndarray
Dynamics = Callable[..., Any]
"""A time-dilated model ``(z, w, forces, omega, s, jacobians=...)`` giving F, A, B, S as
``models.bank_state.bank_state_dynamics`` does (B (N, nz) for one control, (N, nz, m) for m)."""

DEFAULT_SUBSTEPS = 12


@dataclass
class IntervalMaps:
    """Per-interval linear maps of the subproblem dynamics (N intervals, 7 states; with another
    model nz states and Bm, Bp (N, nz, m) for m controls).

    E dz_{k+1} = Phi dz_k + Bm dw_k + Bp dw_{k+1} + S ds_k + (x_prop - z_ref_{k+1}). For the exact
    FOH discretization E is the identity; the trapezoidal rule has E = I - s/2 A_{k+1}.
    """

    Phi: Array  # (N, 7, 7)
    Bm: Array  # (N, 7)
    Bp: Array  # (N, 7)
    S: Array  # (N, 7)
    x_prop: Array  # (N, 7): end of interval k propagated from the reference node k
    E: Array | None = None  # (N, 7, 7); None means the identity
    samples: IntervalSamples | None = None  # every substep of every interval (exact FOH only)
    stacked: Array | None = None  # (N, 7, 10) [Phi | Bm | Bp | S] when the maps are its views

    @property
    def jacobian(self) -> Array:
        """[Phi | B- | B+ | S] (N, 7, 10): the interval's end state differentiated in its
        variables (z_k, w_k, w_{k+1}, s_k)."""
        if self.stacked is not None:
            return self.stacked
        parts = [self.Phi, self.Bm[:, :, None], self.Bp[:, :, None], self.S[:, :, None]]
        return np.concatenate(parts, axis=2)


@dataclass
class IntervalSamples:
    """The reference and its deviation maps at the substeps tau_j = j / substeps, j = 0..substeps,
    of every interval: both ends included, so sample 0 is the node (identity maps) and the last
    is the propagated end (the interval's own maps).

    x(tau_j) = x_bar(tau_j) + Phi_j dz_k + B-_j dw_k + B+_j dw_{k+1} + S_j ds_k to first order,
    so a path limit can be linearized between the nodes with no extra integration. One array
    [x | Phi | B- | B+ | S] (N, J, 7, 11) holds them all; the fields are views of it.
    """

    augmented: Array  # (N, J, 7, 11)

    @classmethod
    def from_parts(cls, x: Array, Phi: Array, Bm: Array, Bp: Array, S: Array) -> IntervalSamples:
        """Samples from separate arrays: x, Bm, Bp, S (N, J, 7) and Phi (N, J, 7, 7)."""
        parts = [x[..., None], Phi, Bm[..., None], Bp[..., None], S[..., None]]
        return cls(np.concatenate(parts, axis=-1))

    @property
    def n_states(self) -> int:
        """Number of states of the samples."""
        return int(self.augmented.shape[-2])

    @property
    def x(self) -> Array:
        """States (N, J, 7)."""
        return self.augmented[..., 0]

    @property
    def Phi(self) -> Array:
        """State-transition maps (N, J, 7, 7)."""
        return self.augmented[..., 1 : self.n_states + 1]

    @property
    def Bm(self) -> Array:
        """Maps of the interval's first bank rate (N, J, 7)."""
        return self.augmented[..., self.n_states + 1]

    @property
    def Bp(self) -> Array:
        """Maps of the interval's second bank rate (N, J, 7)."""
        return self.augmented[..., self.n_states + 2]

    @property
    def S(self) -> Array:
        """Maps of the interval length (N, J, 7)."""
        return self.augmented[..., self.n_states + 3]

    @property
    def jacobian(self) -> Array:
        """[Phi | B- | B+ | S] of every sample (N, J, 7, 10): the state's derivative in the
        interval's variables (z_k, w_k, w_{k+1}, s_k)."""
        return self.augmented[..., 1:]


def _rk4_unit_interval(
    rhs: Callable[[float, np.ndarray], np.ndarray],
    y: np.ndarray,
    substeps: int,
    keep: list[np.ndarray] | None = None,
) -> np.ndarray:
    """Classical RK4 over tau in [0, 1] with ``substeps`` equal steps (all intervals at once).

    With ``keep``, the state after every step is appended to it.
    """
    h = 1.0 / substeps
    tau = 0.0
    for _ in range(substeps):
        k1 = rhs(tau, y)
        k2 = rhs(tau + 0.5 * h, y + (0.5 * h) * k1)
        k3 = rhs(tau + 0.5 * h, y + (0.5 * h) * k2)
        k4 = rhs(tau + h, y + h * k3)
        y = y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        tau += h
        if keep is not None:
            keep.append(y)
    return y


def foh_exact(
    z: Array,
    w: Array,
    s: Array,
    forces: VehicleForces,
    omega: float,
    substeps: int = DEFAULT_SUBSTEPS,
    samples: bool = False,
    dynamics: Dynamics | None = None,
) -> IntervalMaps:
    """Exact FOH maps about the reference nodes ``z`` (K, 7), bank rates ``w`` (K,), lengths ``s``.

    Fixed-step RK4 with ``substeps`` steps in tau on every interval at once (paper 002 Theorem 1
    and eq. 24); the accuracy for a given substep count is measured in the method's docs. With
    ``samples``, every substep is kept as well (``IntervalMaps.samples``). ``dynamics``: another
    model than the bank-state one (numpy form), e.g. ``alpha_bank_state_dynamics`` with ``z``
    (K, 8) and ``w`` (K, 2).
    """
    return interval_maps(
        z[:-1], w[:-1], w[1:], s, forces, omega, substeps, samples, dynamics=dynamics
    )


def interval_maps(
    x0: Array,
    w0: Array,
    w1: Array,
    s: Array,
    forces: VehicleForces,
    omega: float,
    substeps: int = DEFAULT_SUBSTEPS,
    samples: bool = False,
    *,
    compiled: bool = True,
    dynamics: Dynamics | None = None,
) -> IntervalMaps:
    """The exact FOH maps of independent intervals: start states ``x0`` (M, 7), end-point bank
    rates ``w0``, ``w1`` (M,) and lengths ``s`` (M,), all integrated at once.

    ``foh_exact`` calls it with consecutive nodes; the Lagrangian Hessian (``foh_hessian``) with
    perturbed copies of every interval stacked into one batch. The compiled kernel
    (``models.bank_state_sweeps``) runs the same steps when the force models have a compiled
    form and the inputs are real; ``compiled=False`` forces the numpy form. With another
    ``dynamics`` (numpy form), ``x0`` is (M, nz) and ``w0``, ``w1`` (M, m) for m controls: the
    columns of B- and of B+ are then m wide.
    """
    if dynamics is None:
        params = _kernel_parameters(forces, omega, compiled, x0, w0, w1, s)
        if params is not None:
            xa, wa, wb, sa = float_arrays(x0, w0, w1, s)
            aug, kept = interval_maps_kernel(xa, wa, wb, sa, params, substeps, samples)
            return _unpack(aug, kept if samples else None)
    model = bank_state_dynamics if dynamics is None else dynamics
    n, nz = s.size, x0.shape[1]
    m = 1 if np.ndim(w0) == 1 else int(np.shape(w0)[1])
    state = np.zeros((n, nz, nz + 2 * m + 2))
    state[:, :, 0] = x0
    state[:, :, 1 : nz + 1] = np.eye(nz)
    minus, plus, length = slice(nz + 1, nz + 1 + m), slice(nz + 1 + m, nz + 1 + 2 * m), -1

    def rhs(tau: float, y: Array) -> Array:
        x = y[:, :, 0]
        d = model(x, (1.0 - tau) * w0 + tau * w1, forces, omega, s)
        assert d.A is not None and d.B is not None
        b = d.B if d.B.ndim == 3 else d.B[:, :, None]
        out = np.empty_like(y)
        out[:, :, 0] = d.F
        out[:, :, 1:] = np.matmul(d.A, y[:, :, 1:])
        out[:, :, minus] += (1.0 - tau) * b
        out[:, :, plus] += tau * b
        out[:, :, length] += d.S
        return out

    keep: list[Array] | None = [state] if samples else None
    state = _rk4_unit_interval(rhs, state, substeps, keep)
    return _unpack(state, np.stack(keep, axis=1) if keep else None, m)


def _kernel_parameters(
    forces: VehicleForces, omega: float, compiled: bool, *arrays: Array
) -> Array | None:
    """The compiled kernels' parameters, or None to take the numpy form (not asked for, a model
    without a compiled form, or complex input such as a complex-step test's)."""
    if not compiled or any(np.iscomplexobj(a) for a in arrays):
        return None
    return compiled_parameters(forces, omega)


def _unpack(state: Array, kept: Array | None, controls: int = 1) -> IntervalMaps:
    """IntervalMaps from the integrated [x | Phi | B- | B+ | S] (N, 7, 11) and, when kept, every
    substep (N, J, 7, 11); with m ``controls`` B- and B+ are (N, nz, m)."""
    jac = state[:, :, 1:].copy()
    nz, m = state.shape[1], controls
    return IntervalMaps(
        Phi=jac[:, :, :nz],
        Bm=jac[:, :, nz] if m == 1 else jac[:, :, nz : nz + m],
        Bp=jac[:, :, nz + 1] if m == 1 else jac[:, :, nz + m : nz + 2 * m],
        S=jac[:, :, nz + 2 * m],
        x_prop=state[:, :, 0].copy(),
        samples=None if kept is None else IntervalSamples(kept),
        stacked=jac,
    )


def propagate_nodes(
    z: Array,
    w: Array,
    s: Array,
    forces: VehicleForces,
    omega: float,
    substeps: int = DEFAULT_SUBSTEPS,
    *,
    compiled: bool = True,
    dynamics: Dynamics | None = None,
) -> Array:
    """End states of every interval propagated from its own node: the values of ``foh_exact``.

    Same RK4 steps as ``foh_exact`` without the sensitivities (cheaper: no Jacobians).
    """
    w0, w1 = w[:-1], w[1:]
    params = None if dynamics is not None else _kernel_parameters(forces, omega, compiled, z, w, s)
    if params is not None:
        xa, wa, wb, sa = float_arrays(z[:-1], w0, w1, s)
        return propagate_kernel(xa, wa, wb, sa, params, substeps, False)
    x = np.array(z[:-1], dtype=float)
    model = bank_state_dynamics if dynamics is None else dynamics

    def rhs(tau: float, x: Array) -> Array:
        return model(x, (1.0 - tau) * w0 + tau * w1, forces, omega, s, jacobians=False).F

    return _rk4_unit_interval(rhs, x, substeps)


def chain_propagate(
    z0: Array,
    w: Array,
    s: Array,
    forces: VehicleForces,
    omega: float,
    substeps: int = DEFAULT_SUBSTEPS,
    dynamics: Dynamics | None = None,
) -> Array:
    """Nodes (K, 7) of one continuous propagation from ``z0`` under the FOH bank rate ``w``.

    Interval by interval (each step depends on the previous end), used for the initial reference.
    """
    k = s.size + 1
    z = np.empty((k, np.size(z0)))
    z[0] = z0
    for i in range(k - 1):
        z[i + 1] = propagate_nodes(
            z[i : i + 2], w[i : i + 2], s[i : i + 1], forces, omega, substeps, dynamics=dynamics
        )[0]
    return z
