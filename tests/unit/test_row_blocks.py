"""Declarative row blocks: one declaration of each block gives A, b and the cones, with the
changing coefficients and right-hand sides written per build on a fixed pattern."""

from __future__ import annotations

import numpy as np
import pytest

from worker.solver.conic import ConeSpec
from worker.solver.transcription.rows import Columns, RowBlock, RowSystem, Term


def _system() -> tuple[Columns, RowSystem[float]]:
    """x (2), y (1): x0 + 2 y = 3; t x1 <= 4 - t and -x1 <= 1 for data t; |(x0, x1)| <= 1."""
    cols = Columns()
    x = cols.add("x", 2)
    y = cols.add("y")
    blocks: list[RowBlock[float]] = [
        RowBlock("eq", "zero", 1, (Term(0, x[0], 1.0), Term(0, y, 2.0)), b=3.0),
        RowBlock(
            "bounds",
            "nonneg",
            2,
            (Term([0, 1], x[1], [0.0, -1.0], update=lambda t: [t, -1.0]),),
            rhs=lambda t: np.array([4.0 - t, 1.0]),
        ),
        RowBlock("cone", "soc", 3, (Term([1, 2], x, -1.0),), b=[1.0, 0.0, 0.0], soc_dim=3),
    ]
    return cols, RowSystem(blocks, cols.n)


def test_a_b_and_cones_of_a_small_case() -> None:
    cols, system = _system()
    assert cols.n == 3
    assert system.cones == ConeSpec(1, 2, (3,))
    assert (system.start("eq"), system.start("bounds"), system.start("cone")) == (0, 1, 3)
    assert system.rows("cone") == slice(3, 6)
    np.testing.assert_array_equal(
        system.A(0.5).toarray(),
        [[1, 0, 2], [0, 0.5, 0], [0, -1, 0], [0, 0, 0], [-1, 0, 0], [0, -1, 0]],
    )
    np.testing.assert_array_equal(system.b(0.5), [3, 3.5, 1, 1, 0, 0])
    # a new build writes only the new values; the pattern stays
    a2 = system.A(2.0)
    assert a2[1, 1] == 2.0 and a2.nnz == system.A(0.5).nnz
    np.testing.assert_array_equal(system.b(2.0)[1], 2.0)


def test_columns_vector() -> None:
    cols, _ = _system()
    np.testing.assert_array_equal(cols.vector({"y": 4.0, "x": [1.0, 2.0]}), [1, 2, 4])


def test_duplicates_are_summed() -> None:
    system: RowSystem[float] = RowSystem(
        [
            RowBlock(
                "r",
                "nonneg",
                1,
                (Term(0, 0, 1.0), Term(0, 0, 2.0, update=lambda t: t)),
            )
        ],
        1,
    )
    assert system.assembler.has_duplicates
    assert system.A(5.0).toarray()[0, 0] == 6.0


def test_declaration_errors() -> None:
    zero = RowBlock[float]("a", "zero", 1, (Term(0, 0, 1.0),))
    nonneg = RowBlock[float]("b", "nonneg", 1, (Term(0, 0, 1.0),))
    with pytest.raises(ValueError, match="equalities, nonnegatives"):
        RowSystem([nonneg, zero], 1)
    with pytest.raises(ValueError, match="two row blocks"):
        RowSystem([zero, zero], 1)
    with pytest.raises(ValueError, match="outside the block"):
        RowSystem([RowBlock[float]("c", "zero", 1, (Term(1, 0, 1.0),))], 1)
    with pytest.raises(ValueError, match="soc_dim"):
        RowSystem([RowBlock[float]("d", "soc", 4, soc_dim=3)], 1)
