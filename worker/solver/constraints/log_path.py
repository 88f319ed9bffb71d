"""Log-transformed path limits linearized in radius and speed (paper 002 eq. 25-26, generalized).

For each limit p(r, V) <= p_max the subproblem keeps ln p(r, V) <= ln p_max linearized about the
reference: ln p_bar + (p_r / p)(r - r_bar) + (p_V / p)(V - V_bar) <= ln p_max. The paper writes
the exponential-atmosphere form, where ln p is exactly linear in r and only ln V is nonlinear; here
the partials are exact for any atmosphere and include the speed dependence of the scheduled angle
of attack (through CL, CD in the load factor and the heating factor). The second-order term of ln V
becomes the convex penalty w_nl * sum (V - V_bar)^2 / V_bar^2 (eq. 26) in the objective.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worker.solver.constraints.between_nodes import smooth_max_rows
from worker.solver.constraints.path_compiled import log_rows_kernel
from worker.solver.forces import ForceTerms
from worker.solver.path_limits import path_values
from worker.solver.problem import EntryProblem
from worker.solver.transcription.foh_data import InnerRows
from worker.solver.transcription.foh_exact import IntervalSamples

Array = np.ndarray

LIMIT_NAMES = ("heat_rate", "dynamic_pressure", "load_factor")


@dataclass
class LogPathRows:
    """Rows g + g_r (r - r_bar) + g_v (V - V_bar) <= 0, one column per active limit.

    ``g`` is ln(p_bar / p_max) (K, m), ``g_r`` and ``g_v`` the partials of ln p (K, m); ``ratio``
    is p_bar / p_max, reported in the history.
    """

    names: tuple[str, ...]
    g: Array
    g_r: Array
    g_v: Array
    g_a: Array | None = None
    """Partials of ln p in the angle of attack (per degree), where it is a state."""

    @property
    def ratio(self) -> Array:
        """p / p_max at the reference nodes, (K, m)."""
        return np.exp(self.g)

    def take(self, index: Array | slice) -> LogPathRows:
        """The rows at a subset of the points."""
        g_a = None if self.g_a is None else self.g_a[index]
        return LogPathRows(self.names, self.g[index], self.g_r[index], self.g_v[index], g_a)


def active_limits(problem: EntryProblem) -> tuple[str, ...]:
    """Names of the path limits the problem sets, in ``LIMIT_NAMES`` order."""
    lim = problem.limits
    out = []
    if lim.heat_max_W_m2 is not None and problem.heat_model is not None:
        out.append("heat_rate")
    if lim.dynamic_pressure_max_Pa is not None:
        out.append("dynamic_pressure")
    if lim.load_factor_max_g is not None:
        out.append("load_factor")
    return tuple(out)


def log_path_rows(
    problem: EntryProblem, r: Array, v: Array, ft: ForceTerms, *, alpha_state: bool = False
) -> LogPathRows:
    """Linearized ln p <= ln p_max at nodes (r, V) with force terms ``ft`` evaluated there;
    with ``alpha_state`` (``ft`` at the states' own angle of attack) the partials in alpha too:
    the heat rate's alpha factor and the load factor's CL, CD."""
    names = active_limits(problem)
    k = r.size
    g = np.zeros((k, len(names)))
    g_r = np.zeros_like(g)
    g_v = np.zeros_like(g)
    g_a = np.zeros_like(g) if alpha_state else None
    lim = problem.limits
    pv = path_values(problem.forces, problem.heat_model, r, v, ft)
    for j, name in enumerate(names):
        if name == "heat_rate":
            assert lim.heat_max_W_m2 is not None
            g[:, j] = np.log(pv.heat_rate / lim.heat_max_W_m2)
            g_r[:, j] = pv.heat_rate_r / pv.heat_rate
            g_v[:, j] = pv.heat_rate_v / pv.heat_rate
            if g_a is not None and pv.heat_rate_a is not None:
                g_a[:, j] = pv.heat_rate_a / pv.heat_rate
        elif name == "dynamic_pressure":
            assert lim.dynamic_pressure_max_Pa is not None
            g[:, j] = np.log(pv.dynamic_pressure / lim.dynamic_pressure_max_Pa)
            g_r[:, j] = ft.rho_r / ft.rho
            g_v[:, j] = 2.0 / v
        else:
            assert lim.load_factor_max_g is not None
            n2 = ft.lift * ft.lift + ft.drag * ft.drag
            g[:, j] = 0.5 * np.log(n2) - np.log(lim.load_factor_max_g)
            g_r[:, j] = (ft.lift * ft.lift_r + ft.drag * ft.drag_r) / n2
            g_v[:, j] = (ft.lift * ft.lift_v + ft.drag * ft.drag_v) / n2
            if g_a is not None:
                g_a[:, j] = (ft.lift * ft.lift_a + ft.drag * ft.drag_a) / n2
    return LogPathRows(names=names, g=g, g_r=g_r, g_v=g_v, g_a=g_a)


def path_rows_at(
    problem: EntryProblem, r: Array, v: Array, compiled: tuple[Array, Array] | None
) -> LogPathRows:
    """``log_path_rows`` at nondimensional (r, V), the force terms evaluated here: by the
    compiled kernel when ``compiled`` holds its parameters (``path_compiled.limit_parameters``),
    else in numpy."""
    if compiled is None:
        return log_path_rows(problem, r, v, problem.forces.terms(r, v))
    g, g_r, g_v = log_rows_kernel(
        np.ascontiguousarray(r, dtype=np.float64),
        np.ascontiguousarray(v, dtype=np.float64),
        *compiled,
    )
    return LogPathRows(active_limits(problem), g, g_r, g_v)


def inner_path_rows(
    rows: LogPathRows,
    samples: IntervalSamples,
    width: float,
    *,
    exact: bool,
    alpha: int | None = None,
    unit: float = 1.0,
) -> InnerRows:
    """The log path limits between the nodes: per interval and limit, the smooth maximum of the
        samples (``between_nodes.smooth_max_rows``, ``width`` in ln(p / p_max), ``exact``: value at
        the worst sample), from ``rows`` evaluated at the samples (N * J points, interval-major).
        Node rows alone let a sparse grid put a heating peak between two nodes; these close that
        gap. ``alpha``: the index of an angle-of-attack state the rows also depend on, ``unit`` the
    aerodynamic argument (degrees) per unit of that state."""
    n, j = samples.x.shape[:2]
    m = len(rows.names)
    shape = (n, j, m)
    grads = {0: rows.g_r.reshape(shape), 3: rows.g_v.reshape(shape)}
    if alpha is not None and rows.g_a is not None:  # per unit of the alpha state
        grads[alpha] = rows.g_a.reshape(shape) * unit
    g = rows.g.reshape(shape)
    return smooth_max_rows(g, grads, samples, np.full(m, width), exact=exact)
