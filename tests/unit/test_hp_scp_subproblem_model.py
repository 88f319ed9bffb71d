"""The pieces of paper 003's subproblem that its globalization reads back: the quadratic part of
the step's model (what the predicted decrease must count) and the multipliers of the relaxed
rows (what the exact penalty's weight must exceed)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from worker.solver.methods.hp_scp.subproblem import Columns, model_curvature, slacked_multipliers


def test_model_curvature_is_the_full_quadratic_form_less_the_trust_penalty() -> None:
    rng = np.random.default_rng(3)
    n, steps, weight = 9, 6, 0.7
    root = rng.normal(size=(n, n))
    curvature = root @ root.T  # symmetric, as the Lagrangian's blocks
    diag = np.zeros(n)
    diag[:steps] = weight
    full = curvature + np.diag(diag)
    P = sp.triu(sp.csc_matrix(full), format="csc")  # stored as the subproblem stores it
    x = rng.normal(size=n)
    expected = 0.5 * x @ curvature @ x
    # rounding only: a dozen products of order-one numbers
    assert model_curvature(P, x, weight, steps) == pytest.approx(expected, rel=1e-12)


def test_model_curvature_of_a_trust_penalty_alone_is_zero() -> None:
    n, steps, weight = 5, 5, 3.0
    P = sp.diags(np.full(n, weight), format="csc")
    x = np.arange(n, dtype=float)
    assert model_curvature(P, x, weight, steps) == pytest.approx(0.0, abs=1e-12)
    assert model_curvature(None, x, weight, steps) == 0.0


def test_slacked_multipliers_read_a_met_terminal_condition_as_the_difference_of_its_rows() -> None:
    cols = Columns(K=3, L=1, Z=0, T=2)
    weight = 1.0e4
    y = np.zeros(40 + (cols.n - cols.nu_plus))
    y[: cols.collocation_rows] = np.linspace(-2.0, 1.5, cols.collocation_rows)  # largest 2
    signs = y[40:]  # a view: the slacks' sign rows, in column order
    signs[:] = weight  # an unused slack's sign row carries the whole weight
    path = cols.path - cols.nu_plus
    signs[path : path + 3] = [weight, weight - 4.0, weight - 0.5]  # path rows sharing slacks
    cols.rows["terminal"] = 30
    # both one-sided rows of a met condition active: an interior-point split of the weight
    y[30:34] = [3333.0, 3333.5, 3332.0, 3333.0]
    assert slacked_multipliers(y, cols, weight) == pytest.approx(4.0)
    y[32] = 3323.0  # the second condition's multiplier is now 10
    assert slacked_multipliers(y, cols, weight) == pytest.approx(10.0)
