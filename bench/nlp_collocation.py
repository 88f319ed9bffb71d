"""A general NLP transcription of an entry problem: the independent reference of the benchmarks.

Hermite–Simpson collocation in separated form (states at the nodes and at the interval
midpoints; Betts, Practical Methods for Optimal Control, 2nd ed., sec. 4.6.4), the controls at
the nodes and linear over each interval, on a uniform time mesh, solved by IPOPT through CasADi.
The problem is read from the same problem document the service takes (SI values): the point-mass
equations over a spherical, optionally rotating planet (paper 000 eq. 1) or paper 001's flat-
Earth model (eq. 1); the exponential or U.S. 1976 atmosphere, polynomial aerodynamics (CD in
alpha or in CL) or a parabolic polar, the angle-of-attack laws of the contract (velocity
schedule, table, constant, optimized: a control, or a state with its rate the control when its
rate is limited, paper 003 eq. 1) and the force models of ``bench.nlp_models``; heat-rate (with
its alpha factor), dynamic-pressure and load-factor limits; fixed, range or soft terminal
conditions (soft ones held hard, which has the same optimum as their exact penalty); a fixed or
free (optionally bounded) final time; bank limits, symmetric or not (the bank a state and its
rate the control when a rate limit is given); given initial bank and alpha; great-circle or
lat/lon no-fly zones; and any weighted sum of the objectives maximum terminal velocity, minimum
heat load, minimum time and extreme final latitude or longitude. Not covered: aerodynamic
tables, waypoints, phases, propulsion, minimum control effort (each refused by name).

CasADi is an optional benchmark dependency (``pip install -e '.[bench]'``); nothing in the
service imports this module.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench import nlp_models
from worker.solver.trajectory import TIME_STATE_NAMES as STATE_NAMES

GUESS_ALPHA_DEG = 20.0
"""Constant angle of attack of the guess's propagation when alpha is optimized."""

OBJECTIVE_SIGNS = {
    "max_terminal_velocity": -1.0,
    "min_time": 1.0,
    "min_heat_load": 1.0,
    "max_final_latitude": -1.0,
    "min_final_latitude": 1.0,
    "max_final_longitude": -1.0,
    "min_final_longitude": 1.0,
}
"""The objective terms the transcription covers and their sign in the minimized sum."""


@dataclass
class NlpSolution:
    """What one IPOPT solve gave: its status, objective (SI: the term's own value for a single
    term, else the weighted sum with max terms negated), solve wall time (IPOPT only, the NLP
    already built), iterations, and the solution's arrays (None when IPOPT failed)."""

    status: str
    objective: float
    solve_s: float
    iterations: int
    final_time_s: float
    terms: dict[str, float] = field(default_factory=dict)
    arrays: dict[str, np.ndarray] | None = None

    @property
    def converged(self) -> bool:
        """IPOPT's own verdict: a local optimum found (to tolerance or to an acceptable level)."""
        return self.status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")


def _target(terminal: dict[str, Any], name: str) -> float | None:
    """A terminal condition's target value (SI, degrees), or None when it is free."""
    entry = terminal.get(name)
    if entry is None:
        return None
    if isinstance(entry, int | float):
        return float(entry)
    if entry.get("kind") in ("fixed", "soft"):
        return float(entry["value"])
    return None


def _range(terminal: dict[str, Any], name: str) -> tuple[float, float] | None:
    """A range terminal condition's bounds (SI, degrees), or None."""
    entry = terminal.get(name)
    if isinstance(entry, dict) and entry.get("kind") == "range":
        return float(entry["lo"]), float(entry["hi"])
    return None


def objective_terms(document: dict[str, Any]) -> list[tuple[str, float]]:
    """(name, weight) of each objective term of the document."""
    objective = document["objective"]
    if isinstance(objective, str):
        return [(objective, 1.0)]
    terms = objective["terms"] if isinstance(objective, dict) else objective
    return [(t["name"], float(t.get("weight", 1.0))) for t in terms]


class EntryNlp:
    """The NLP of one problem document on ``intervals`` uniform intervals, built once and
    solvable many times (each solve from the initial guess last set). ``start`` picks the
    guess: 0 the constant-bank propagation closest to the terminal targets, 1 the closest of
    the other bank sign (another local basin)."""

    def __init__(
        self,
        document: dict[str, Any],
        intervals: int,
        max_iter: int = 500,
        linear_guess: bool = False,
        start: int = 0,
        tol: float = 1e-8,
        build: bool = True,
    ) -> None:
        import casadi as ca

        self.ca = ca
        self.doc = document
        self.n = intervals
        self.max_iter = max_iter
        self.linear_guess = linear_guess
        self.start = start
        self.tol = tol
        for what in ("waypoints", "phases"):
            if document.get(what):
                raise ValueError(f"the NLP transcription does not cover {what}")
        planet = document["planet"]
        self.radius = float(planet.get("radius_m", 6378140.0))
        mu = planet.get("mu_m3_s2")
        self.g0 = (
            float(mu) / self.radius**2 if mu is not None else float(planet.get("g0_m_s2", 9.81))
        )
        self.t_unit = math.sqrt(self.radius / self.g0)
        self.v_unit = math.sqrt(self.radius * self.g0)
        omega = float(planet.get("rotation_rate_rad_s", 7.292115e-5))
        self.omega = omega * self.t_unit if planet.get("rotation", False) else 0.0
        self.density = nlp_models.density(ca, planet["atmosphere"])
        vehicle = document["vehicle"]
        if vehicle.get("propulsion"):
            raise ValueError("the NLP transcription does not cover propulsion")
        self.area_over_mass = float(vehicle["reference_area_m2"]) / float(vehicle["mass_kg"])
        aero = vehicle["aerodynamics"]
        self.flat = planet.get("model", "spherical") == "flat"
        self.coefficients = nlp_models.coefficients(ca, aero)
        self.polar = aero.get("model") == "parabolic_polar"
        attack = vehicle.get("angle_of_attack") or {}
        limits = document.get("control_limits") or {}
        self.alpha_of_v = None if self.polar else nlp_models.alpha_law(ca, attack)
        self.alpha_free = not self.polar and self.alpha_of_v is None
        path = document.get("path_constraints") or {}
        self.heat = nlp_models.heat_rate(path.get("heat_rate") or {})
        self.bank_max = math.radians(float(limits.get("bank_max_deg", 80.0)))
        low = limits.get("bank_min_deg")
        self.bank_min = -self.bank_max if low is None else math.radians(float(low))
        rate = limits.get("bank_rate_max_deg_s")
        self.bank_rate_max = None if rate is None else math.radians(float(rate)) * self.t_unit
        if self.polar:  # lambda within its bounds, a control
            self.att_range = (
                float(aero.get("lambda_min", 0.0)),
                float(aero.get("lambda_max", 1.0)),
            )
            self.att_rate_max = None
        elif self.alpha_free:
            self.att_range = (
                math.radians(float(attack["min_deg"])),
                math.radians(float(attack["max_deg"])),
            )
            a_rate = attack.get("rate_max_deg_s", limits.get("alpha_rate_max_deg_s"))
            self.att_rate_max = (
                None if a_rate is None else math.radians(float(a_rate)) * self.t_unit
            )
        else:
            self.att_range = (0.0, 0.0)
            self.att_rate_max = None
        self.has_att = self.polar or self.alpha_free
        # layout: states = 6 point-mass states, then the bank (rate-limited), then the attitude
        # variable (rate-limited alpha); controls = bank or its rate, then the attitude or its rate
        self.bank_state = self.bank_rate_max is not None
        self.att_state = self.has_att and self.att_rate_max is not None
        self.nx = 6 + int(self.bank_state) + int(self.att_state)
        self.nu = 1 + int(self.has_att)
        self.i_att_x = 6 + int(self.bank_state)
        if build:  # without it, only the model (rates, path) is there: for tests
            self._build()

    # -- models (SI where the contract is SI, nondimensional states) --------------------------
    def _alpha_deg(self, v_m_s: Any, att: Any) -> Any:
        """alpha (deg) from the law, or the optimized alpha (rad) in degrees; None for a polar."""
        if self.polar:
            return None
        if self.alpha_of_v is not None:
            return self.alpha_of_v(v_m_s)
        return att * (180.0 / math.pi)

    def _forces(self, r: Any, v: Any, att: Any = None) -> tuple[Any, Any, Any, Any, Any]:
        """Lift and drag accelerations (g0 units), density (kg/m^3), speed (m/s), alpha (deg);
        ``att`` the optimized alpha (rad) or a polar's lambda."""
        h = (r - 1.0) * self.radius
        rho = self.density(h)
        v_si = v * self.v_unit
        alpha = self._alpha_deg(v_si, att)
        cl, cd = self.coefficients(att if self.polar else alpha)
        q_over_mass = 0.5 * rho * v_si * v_si * self.area_over_mass / self.g0
        return q_over_mass * cl, q_over_mass * cd, rho, v_si, alpha

    def rates(self, x: Any, bank: Any, att: Any = None) -> Any:
        """d/dt of [r, theta, phi, V, gamma, psi] (paper 000 eq. 1, nondimensional), or of
        paper 001's flat-Earth model (eq. 1) on the same states."""
        ca = self.ca
        r, _, phi, v, gam, psi = (x[i] for i in range(6))
        lift, drag, _, _, _ = self._forces(r, v, att)
        if self.flat:
            return ca.vertcat(
                v * gam,
                v * ca.sin(psi),
                v * ca.cos(psi),
                -drag,
                (lift * ca.cos(bank) - 1.0) / v + v,
                lift * ca.sin(bank) / v,
            )
        w = self.omega
        sg, cg, sp, cp, sf, cf = (
            ca.sin(gam),
            ca.cos(gam),
            ca.sin(psi),
            ca.cos(psi),
            ca.sin(phi),
            ca.cos(phi),
        )
        dr = v * sg
        dtheta = v * cg * sp / (r * cf)
        dphi = v * cg * cp / r
        dv = -drag - sg / (r * r) + w * w * r * cf * (sg * cf - cg * sf * cp)
        dgam = (
            lift * ca.cos(bank) / v
            + (v * v - 1.0 / r) * cg / (r * v)
            + 2.0 * w * cf * sp
            + w * w * r * cf * (cg * cf + sg * cp * sf) / v
        )
        dpsi = (
            lift * ca.sin(bank) / (v * cg)
            + v * cg * sp * ca.tan(phi) / r
            - 2.0 * w * (ca.tan(gam) * cp * cf - sf)
            + w * w * r * sp * sf * cf / (v * cg)
        )
        return ca.vertcat(dr, dtheta, dphi, dv, dgam, dpsi)

    def path(self, x: Any, att: Any = None) -> dict[str, Any]:
        """Heat rate (W/m^2), dynamic pressure (Pa), load factor (g)."""
        ca = self.ca
        lift, drag, rho, v_si, alpha = self._forces(x[0], x[3], att)
        return {
            "heat_rate": self.heat(rho, v_si, alpha),
            "dynamic_pressure": 0.5 * rho * v_si * v_si,
            "load_factor": ca.sqrt(lift * lift + drag * drag),
        }

    def attitude(self, x: Any, u: Any) -> tuple[Any, Any]:
        """(bank, attitude variable) at a collocation point from its state and control."""
        bank = x[6] if self.bank_state else u[0]
        if not self.has_att:
            return bank, None
        return bank, (x[self.i_att_x] if self.att_state else u[1])

    def f(self, x: Any, u: Any) -> Any:
        """The collocated rates: the point-mass rates, then those of the bank and attitude
        states (their rates are the controls)."""
        ca = self.ca
        bank, att = self.attitude(x, u)
        out = [self.rates(x, bank, att)]
        if self.bank_state:
            out.append(u[0])
        if self.att_state:
            out.append(u[1])
        return ca.vertcat(*out)

    # -- transcription -------------------------------------------------------------------------
    def _build(self) -> None:
        ca = self.ca
        doc, n = self.doc, self.n
        opti = ca.Opti()
        X = opti.variable(self.nx, n + 1)  # nodes
        Xm = opti.variable(self.nx, n)  # midpoints
        U = opti.variable(self.nu, n + 1)
        # the control linear over each interval: its midpoint value the mean of the nodes'. With a
        # free midpoint control, an objective that leaves the interior free (e.g. one pinned by a
        # terminal limit) lets nodes and midpoints alternate, which no flown control reproduces
        Um = 0.5 * (U[:, :n] + U[:, 1:])
        final = doc.get("final_time") or {}
        fixed_tf = final.get("kind") == "fixed"
        t0 = float(doc["initial_state"].get("time_s", 0.0))
        tf = (float(final["value_s"]) - t0) / self.t_unit if fixed_tf else opti.variable()
        h = tf / n
        heat_terms = []
        path = doc.get("path_constraints") or {}
        caps = {
            "heat_rate": (path.get("heat_rate") or {}).get("max_W_m2"),
            "dynamic_pressure": (path.get("dynamic_pressure") or {}).get("max_Pa"),
            "load_factor": (path.get("load_factor") or {}).get("max_g"),
        }
        node_path = [self.path(X[:, k], self.attitude(X[:, k], U[:, k])[1]) for k in range(n + 1)]
        rates = [self.f(X[:, k], U[:, k]) for k in range(n + 1)]
        mid_path = []
        for k in range(n):
            fk, fk1, fm = rates[k], rates[k + 1], self.f(Xm[:, k], Um[:, k])
            opti.subject_to(Xm[:, k] == 0.5 * (X[:, k] + X[:, k + 1]) + h / 8.0 * (fk - fk1))
            opti.subject_to(X[:, k + 1] - X[:, k] == h / 6.0 * (fk + 4.0 * fm + fk1))
            mid = self.path(Xm[:, k], self.attitude(Xm[:, k], Um[:, k])[1])
            heat_terms.append(
                h
                / 6.0
                * (
                    node_path[k]["heat_rate"]
                    + 4.0 * mid["heat_rate"]
                    + node_path[k + 1]["heat_rate"]
                )
            )
            mid_path.append(mid)
        for point in node_path + mid_path:  # the limits at the nodes and at the midpoints
            for name, cap in caps.items():
                if cap is not None:
                    opti.subject_to(point[name] / float(cap) <= 1.0)
        for zone in doc.get("no_fly_zones") or []:
            self._zone(opti, zone, X, Xm)
        self._bounds(opti, X, Xm, U, Um)
        if not fixed_tf:
            t_max = final.get("max_s")
            hi = (float(t_max) - t0) if t_max is not None else 5000.0
            opti.subject_to(opti.bounded(100.0 / self.t_unit, tf, hi / self.t_unit))
        self._boundary(opti, X)
        terms = self._objective_terms(X, tf, heat_terms, fixed_tf)
        names = objective_terms(doc)
        if len(names) == 1:  # the term alone, nondimensional: the scaling IPOPT is used to
            name = names[0][0]
            opti.minimize(OBJECTIVE_SIGNS[name] * terms[name][0])
        else:  # the caller's weighted sum in the terms' SI units, one common factor
            total = sum(OBJECTIVE_SIGNS[nm] * w * terms[nm][0] * terms[nm][1] for nm, w in names)
            opti.minimize(total / 1000.0)
        self._terms = {nm: terms[nm] for nm, _ in names}
        self._weights = dict(names)
        opti.solver(
            "ipopt",
            {"print_time": False},
            {"print_level": 0, "sb": "yes", "max_iter": self.max_iter, "tol": self.tol},
        )
        self.opti, self.X, self.Xm, self.U, self.Um = opti, X, Xm, U, Um
        self.tf = tf
        self.t0 = t0
        self.fixed_tf = fixed_tf
        self._guess()

    def _zone(self, opti: Any, zone: dict[str, Any], X: Any, Xm: Any) -> None:
        """Keep nodes and midpoints outside a no-fly zone."""
        ca = self.ca
        lat_c = math.radians(float(zone["center_latitude_deg"]))
        lon_c = math.radians(float(zone["center_longitude_deg"]))
        radius = (
            math.radians(float(zone["radius_deg"]))
            if zone.get("radius_deg") is not None
            else float(zone["radius_km"]) * 1000.0 / self.radius
        )
        for cols in (X, Xm):
            lon, lat = cols[1, :], cols[2, :]
            if zone.get("metric", "great_circle") == "great_circle":
                cos_d = math.sin(lat_c) * ca.sin(lat) + math.cos(lat_c) * ca.cos(lat) * ca.cos(
                    lon - lon_c
                )
                opti.subject_to(cos_d <= math.cos(radius))
            else:
                opti.subject_to((lat - lat_c) ** 2 + (lon - lon_c) ** 2 >= radius**2)

    def _bounds(self, opti: Any, X: Any, Xm: Any, U: Any, Um: Any) -> None:
        """Control, attitude and state bounds at the nodes and the midpoints (a midpoint control
        is the mean of two bounded node controls, so only the nodes' controls are bounded)."""
        bank_rate = self.bank_rate_max or 0.0
        att_rate = self.att_rate_max or 0.0
        for cols, u, nodes in ((X, U, True), (Xm, Um, False)):
            if self.bank_state:
                opti.subject_to(opti.bounded(self.bank_min, cols[6, :], self.bank_max))
                if nodes:
                    opti.subject_to(opti.bounded(-bank_rate, u[0, :], bank_rate))
            elif nodes:
                opti.subject_to(opti.bounded(self.bank_min, u[0, :], self.bank_max))
            if self.has_att and (self.att_state or nodes):
                att = cols[self.i_att_x, :] if self.att_state else u[1, :]
                opti.subject_to(opti.bounded(self.att_range[0], att, self.att_range[1]))
            if self.att_state and nodes:
                opti.subject_to(opti.bounded(-att_rate, u[1, :], att_rate))
            opti.subject_to(cols[0, :] >= 1.0)
            opti.subject_to(cols[3, :] >= 0.01)

    def _boundary(self, opti: Any, X: Any) -> None:
        """The initial state (and given initial bank and alpha) and the terminal conditions."""
        n = self.n
        init = self.doc["initial_state"]
        x0 = self._nd_state(init)
        for i in range(6):
            opti.subject_to(X[i, 0] == x0[i])
        if self.bank_state and init.get("bank_deg") is not None:
            opti.subject_to(X[6, 0] == math.radians(float(init["bank_deg"])))
        attack = self.doc["vehicle"].get("angle_of_attack") or {}
        alpha0 = init.get("alpha_deg", attack.get("initial_deg"))
        if self.att_state and self.alpha_free and alpha0 is not None:
            opti.subject_to(X[self.i_att_x, 0] == math.radians(float(alpha0)))
        terminal = self.doc["terminal"]
        for i, name in enumerate(STATE_NAMES):
            target = _target(terminal, name)
            if target is not None:
                opti.subject_to(X[i, n] == self._nd_value(i, target))
            bounds = _range(terminal, name)
            if bounds is not None:
                lo, hi = (self._nd_value(i, b) for b in bounds)
                opti.subject_to(opti.bounded(lo, X[i, n], hi))
        energy = self.doc.get("energy") or {}
        if "final" in energy and _target(terminal, "velocity_m_s") is None:
            e_f = float(energy["final"])  # e = 1/r - V^2/2 (paper 000 eq. 7)
            opti.subject_to(1.0 / X[0, n] - 0.5 * X[3, n] ** 2 == e_f)

    def _objective_terms(
        self, X: Any, tf: Any, heat_terms: list[Any], fixed_tf: bool
    ) -> dict[str, tuple[Any, float]]:
        """Each objective term the document names: (nondimensional expression, SI factor)."""
        ca, n = self.ca, self.n
        out: dict[str, tuple[Any, float]] = {}
        for name, _ in objective_terms(self.doc):
            if name not in OBJECTIVE_SIGNS:
                raise ValueError(f"the NLP transcription does not cover objective {name!r}")
            if name == "max_terminal_velocity":
                out[name] = (X[3, n], self.v_unit)
            elif name == "min_time":
                if fixed_tf:
                    raise ValueError("minimum time needs a free final time")
                out[name] = (tf, self.t_unit)
            elif name == "min_heat_load":
                out[name] = (ca.sum1(ca.vertcat(*heat_terms)) / 1.0e6, 1.0e6 * self.t_unit)
            elif name.endswith("latitude"):
                out[name] = (X[2, n], 180.0 / math.pi)
            else:
                out[name] = (X[1, n], 180.0 / math.pi)
        return out

    def _nd_state(self, state: dict[str, Any]) -> list[float]:
        return [self._nd_value(i, float(state[name])) for i, name in enumerate(STATE_NAMES)]

    def _nd_value(self, i: int, value: float) -> float:
        if i == 0:
            return 1.0 + value / self.radius
        if i == 3:
            return value / self.v_unit
        return math.radians(value)

    def _guess_att(self) -> float | None:
        """The attitude variable of the guess: lambda 1 for a polar, 20 deg of optimized alpha."""
        if self.polar:
            return min(max(1.0, self.att_range[0]), self.att_range[1])
        if self.alpha_free:
            return min(max(math.radians(GUESS_ALPHA_DEG), self.att_range[0]), self.att_range[1])
        return None

    def _sweep(self) -> list[tuple[float, np.ndarray, float, float]]:
        """Constant-bank propagations (RK4) within the bank limits: (terminal miss, states,
        span, bank) of each that stays above the ground; for a free final time, flown until the
        terminal altitude."""
        ca = self.ca
        x = ca.MX.sym("x", 6)
        b = ca.MX.sym("b")
        att = self._guess_att()
        rhs = ca.Function("rhs", [x, b], [self.rates(x, b, att)])
        init = self._nd_state(self.doc["initial_state"])
        terminal = self.doc["terminal"]
        h_target = _target(terminal, "altitude_m")
        h_range = _range(terminal, "altitude_m")
        if h_target is None and h_range is not None:
            h_target = h_range[0]
        r_end = 1.0 + (h_target or 0.0) / self.radius
        final = self.doc.get("final_time") or {}
        t_total = float(self.tf) if self.fixed_tf else 4000.0 / self.t_unit
        steps = 4 * self.n if self.fixed_tf else 2000
        out = []
        for deg in range(-80, 81, 10):
            bank = math.radians(deg)
            if not self.bank_min - 1e-9 <= bank <= self.bank_max + 1e-9:
                continue
            xs = [np.array(init)]
            dt = t_total / steps
            reached = None
            for j in range(steps):
                xj = xs[-1]
                k1 = np.array(rhs(xj, bank)).ravel()
                k2 = np.array(rhs(xj + 0.5 * dt * k1, bank)).ravel()
                k3 = np.array(rhs(xj + 0.5 * dt * k2, bank)).ravel()
                k4 = np.array(rhs(xj + dt * k3, bank)).ravel()
                xs.append(xj + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4))
                if not self.fixed_tf and xs[-1][0] <= r_end:
                    reached = (j + 1) * dt
                    break
                if xs[-1][0] < 1.0 or not np.all(np.isfinite(xs[-1])):
                    break
            span = reached if reached is not None else (t_total if len(xs) == steps + 1 else None)
            if span is None:
                continue
            arr = np.array(xs)
            miss = 0.0
            for i, name in enumerate(STATE_NAMES):
                target = _target(terminal, name)
                if target is not None:
                    miss += (arr[-1, i] - self._nd_value(i, target)) ** 2
            out.append((miss, arr, span, bank))
        del final
        return sorted(out, key=lambda item: item[0])

    def _guess(self) -> None:
        """Set the initial guess of ``start``: the sweep's closest propagation (start 0) or the
        closest of the other bank sign (start 1); a straight line to each fixed target on top
        when ``linear_guess``."""
        sweep = self._sweep()
        if not sweep:
            raise ValueError("no constant-bank propagation stays above the ground")
        choice = sweep[0]
        if self.start % 2 == 1:
            other = [s for s in sweep if s[3] * choice[3] < 0 or (choice[3] == 0 and s[3] != 0)]
            choice = other[0] if other else sweep[min(1, len(sweep) - 1)]
        _, arr, span, bank = choice
        init = self._nd_state(self.doc["initial_state"])
        terminal = self.doc["terminal"]
        t = np.linspace(0.0, span, arr.shape[0])
        tn = np.linspace(0.0, span, self.n + 1)
        tm = 0.5 * (tn[:-1] + tn[1:])
        nodes = np.array([np.interp(tn, t, arr[:, i]) for i in range(6)])
        mids = np.array([np.interp(tm, t, arr[:, i]) for i in range(6)])
        if self.linear_guess:  # straight from the initial state to each fixed terminal target
            for i, name in enumerate(STATE_NAMES):
                target = _target(terminal, name)
                if target is not None:
                    end = self._nd_value(i, target)
                    nodes[i] = init[i] + (end - init[i]) * tn / span
                    mids[i] = init[i] + (end - init[i]) * tm / span
        att = self._guess_att()
        extra_x, extra_u = [], [bank if not self.bank_state else 0.0]
        if self.bank_state:
            extra_x.append(bank)
        if self.has_att:
            assert att is not None
            if self.att_state:
                extra_x.append(att)
                extra_u.append(0.0)
            else:
                extra_u.append(att)
        nodes = np.vstack([nodes] + [np.full(self.n + 1, v) for v in extra_x])
        mids = np.vstack([mids] + [np.full(self.n, v) for v in extra_x])
        self.set_start(
            nodes,
            mids,
            np.array([np.full(self.n + 1, v) for v in extra_u]),
            np.array([np.full(self.n, v) for v in extra_u]),
            span,
        )

    def set_start(
        self, nodes: np.ndarray, mids: np.ndarray, u: np.ndarray, um: np.ndarray, span: float
    ) -> None:
        """Set the initial guess from arrays on this mesh (span nondimensional)."""
        opti = self.opti
        opti.set_initial(self.X, nodes)
        opti.set_initial(self.Xm, mids)
        opti.set_initial(self.U, u)
        del um  # the midpoint controls follow from the nodes'
        if not self.fixed_tf:
            opti.set_initial(self.tf, span)

    def warm_from(self, arrays: dict[str, np.ndarray]) -> None:
        """Start from another mesh's solution, interpolated in time onto this mesh."""
        t_src = arrays["t"]  # nondimensional times of nodes and midpoints, interleaved
        x_src, u_src = arrays["x"], arrays["u"]
        span = float(t_src[-1])
        tn = np.linspace(0.0, span, self.n + 1)
        tm = 0.5 * (tn[:-1] + tn[1:])

        def on(t: np.ndarray, values: np.ndarray) -> np.ndarray:
            return np.array([np.interp(t, t_src, row) for row in values])

        self.set_start(on(tn, x_src), on(tm, x_src), on(tn, u_src), on(tm, u_src), span)

    def solve(self) -> NlpSolution:
        """Solve from the guess last set; the wall time is IPOPT's solve alone."""
        start = time.perf_counter()
        arrays = None
        terms: dict[str, float] = {}
        try:
            sol = self.opti.solve()
            stats = sol.stats()
            terms = {nm: float(sol.value(e)) * s for nm, (e, s) in self._terms.items()}
            tf = float(sol.value(self.tf)) if not self.fixed_tf else float(self.tf)
            arrays = self._arrays(sol, tf)
        except RuntimeError:
            stats = self.opti.stats()
            tf = float("nan")
        elapsed = time.perf_counter() - start
        if not terms:
            value = float("nan")
        elif len(terms) == 1:
            value = next(iter(terms.values()))
        else:
            value = sum(-v * self._weights[k] if OBJECTIVE_SIGNS[k] < 0 else v * self._weights[k]
                        for k, v in terms.items())  # fmt: skip
        return NlpSolution(
            status=str(stats.get("return_status")),
            objective=value,
            solve_s=elapsed,
            iterations=int(stats.get("iter_count", -1)),
            final_time_s=tf * self.t_unit,
            terms=terms,
            arrays=arrays,
        )

    def _arrays(self, sol: Any, tf: float) -> dict[str, np.ndarray]:
        """Nodes and midpoints interleaved in time: t (nondimensional), x, u, and the rates f."""
        x = np.atleast_2d(sol.value(self.X)).reshape(self.nx, self.n + 1)
        xm = np.atleast_2d(sol.value(self.Xm)).reshape(self.nx, self.n)
        u = np.atleast_2d(sol.value(self.U)).reshape(self.nu, self.n + 1)
        um = np.atleast_2d(sol.value(self.Um)).reshape(self.nu, self.n)
        t = np.linspace(0.0, tf, 2 * self.n + 1)
        xs = np.empty((self.nx, 2 * self.n + 1))
        us = np.empty((self.nu, 2 * self.n + 1))
        xs[:, 0::2], xs[:, 1::2] = x, xm
        us[:, 0::2], us[:, 1::2] = u, um
        return {"t": t, "x": xs, "u": us}
