"""Declarative row blocks of a conic subproblem: each block of rows is declared once (its cone,
its coefficients on the variable columns, its right-hand side) and A, b and the cone list follow.

A builder lists its blocks in row order (equalities, then nonnegative rows, then second-order
cones, Clarabel's standard form A x + s = b, s in K); ``RowSystem`` fixes the sparsity pattern
once and, per iteration, writes only the coefficients and right-hand sides a block marks as
changing. ``Columns`` is the matching declaration of the decision vector's variable groups.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Generic, Literal, TypeVar

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from worker.solver.conic import ConeSpec, SparseAssembler

Array = np.ndarray
D = TypeVar("D")
Cone = Literal["zero", "nonneg", "soc"]
_CONE_ORDER = {"zero": 0, "nonneg": 1, "soc": 2}


@dataclass(frozen=True)
class Term(Generic[D]):
    """Coefficients of one group of variables in a block: A[block start + rows, cols] = value.

    ``rows`` (local to the block) and ``cols`` broadcast to one shape; ``value`` is the constant
    coefficient (broadcast to it). ``update``, when given, returns the coefficients of an
    iteration in that shape (or None to keep ``value``).
    """

    rows: ArrayLike
    cols: ArrayLike
    value: ArrayLike = 0.0
    update: Callable[[D], ArrayLike | None] | None = None


@dataclass(frozen=True)
class RowBlock(Generic[D]):
    """``size`` consecutive rows in one cone: sum of its terms + s = b, s in the cone.

    ``b`` is the constant right-hand side (broadcast to ``size``); ``rhs``, when given, returns
    the right-hand side of an iteration instead. A second-order block holds ``size / soc_dim``
    cones of dimension ``soc_dim`` one after the other.
    """

    name: str
    cone: Cone
    size: int
    terms: Sequence[Term[D]] = ()
    b: ArrayLike = 0.0
    rhs: Callable[[D], ArrayLike] | None = None
    soc_dim: int = 0


class Columns:
    """The decision vector as named groups of columns, laid out in the order they are added."""

    def __init__(self) -> None:
        self.n = 0
        self.groups: dict[str, NDArray[np.int64]] = {}

    def add(self, name: str, *shape: int) -> NDArray[np.int64]:
        """Append a group of ``shape`` columns; returns their indices in that shape."""
        size = int(np.prod(shape)) if shape else 1
        cols = (self.n + np.arange(size, dtype=np.int64)).reshape(shape)
        self.groups[name] = cols
        self.n += size
        return cols

    def vector(self, values: Mapping[str, ArrayLike]) -> NDArray[np.float64]:
        """A vector over the columns (e.g. q): each named group set to its value, zero
        elsewhere."""
        out = np.zeros(self.n)
        for name, value in values.items():
            out[self.groups[name]] = value
        return out


class RowSystem(Generic[D]):
    """A, b and the cones of a list of row blocks, on a sparsity pattern fixed at construction.

    Duplicate (row, column) pairs are summed (the assembler's rule); without any, each build
    copies the constant CSC data and writes the changing coefficients into their slots.
    """

    def __init__(self, blocks: Sequence[RowBlock[D]], n_cols: int) -> None:
        order = [_CONE_ORDER[blk.cone] for blk in blocks]
        if order != sorted(order):
            raise ValueError("row blocks must come as equalities, nonnegatives, then cones")
        rows: list[Array] = []
        cols: list[Array] = []
        vals: list[Array] = []
        b: list[Array] = []
        self.blocks = tuple(blocks)
        self._slices: dict[str, slice] = {}
        updates: list[tuple[Callable[[D], ArrayLike | None], slice, tuple[int, ...]]] = []
        self._rhs: list[tuple[Callable[[D], ArrayLike], slice]] = []
        counts = {"zero": 0, "nonneg": 0}
        soc: list[int] = []
        start = count = 0
        for blk in blocks:
            if blk.name in self._slices:
                raise ValueError(f"two row blocks are called {blk.name!r}")
            rows_of = slice(start, start + blk.size)
            self._slices[blk.name] = rows_of
            if blk.cone == "soc":
                if blk.soc_dim < 1 or blk.size % blk.soc_dim:
                    raise ValueError(f"block {blk.name!r}: size is not a multiple of soc_dim")
                soc.extend([blk.soc_dim] * (blk.size // blk.soc_dim))
            else:
                counts[blk.cone] += blk.size
            for term in blk.terms:
                r, c = np.broadcast_arrays(
                    np.asarray(term.rows, dtype=np.int64), np.asarray(term.cols, dtype=np.int64)
                )
                if r.size and (r.min() < 0 or r.max() >= blk.size):
                    raise ValueError(f"block {blk.name!r}: a term row lies outside the block")
                rows.append(start + r.ravel())
                cols.append(c.ravel())
                vals.append(np.broadcast_to(np.asarray(term.value, dtype=float), r.shape).ravel())
                if term.update is not None and r.size:
                    updates.append((term.update, slice(count, count + r.size), r.shape))
                count += r.size
            b.append(np.broadcast_to(np.asarray(blk.b, dtype=float), (blk.size,)))
            if blk.rhs is not None and blk.size:
                self._rhs.append((blk.rhs, rows_of))
            start += blk.size
        self.m = start
        self.n = n_cols
        self.cones = ConeSpec(counts["zero"], counts["nonneg"], tuple(soc))
        empty = np.zeros(0, dtype=np.int64)
        self.assembler = SparseAssembler(
            np.concatenate(rows) if rows else empty,
            np.concatenate(cols) if cols else empty,
            (self.m, n_cols),
        )
        self._vals = np.concatenate(vals) if vals else np.zeros(0)
        self._b = np.concatenate(b) if b else np.zeros(0)
        self._direct = not self.assembler.has_duplicates
        pos = self.assembler.positions
        self._updates = [
            (fn, pos[sl].reshape(shape) if self._direct else sl, shape) for fn, sl, shape in updates
        ]
        self._data = self.assembler.assemble_data(self._vals) if self._direct else None

    def rows(self, name: str) -> slice:
        """The rows of block ``name``."""
        return self._slices[name]

    def start(self, name: str) -> int:
        """The first row of block ``name``."""
        return int(self._slices[name].start)

    def A(self, d: D) -> sp.csc_matrix:
        """A for data ``d``: the constant coefficients with every term's update written in."""
        if self._data is not None:
            data = self._data.copy()
            for fn, slots, _ in self._updates:
                value = fn(d)
                if value is not None:
                    data[slots] = value
            return self.assembler.matrix(data)
        vals = self._vals.copy()
        for fn, where, shape in self._updates:
            value = fn(d)
            if value is not None:
                vals[where] = np.broadcast_to(np.asarray(value, dtype=float), shape).ravel()
        return self.assembler.assemble(vals)

    def b(self, d: D) -> NDArray[np.float64]:
        """b for data ``d``: the constant right-hand sides with every block's ``rhs`` written
        in."""
        b = self._b.copy()
        for fn, rows_of in self._rhs:
            b[rows_of] = fn(d)
        return b
