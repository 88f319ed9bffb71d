"""Second-order-cone program in Clarabel's standard form, and a fixed-pattern sparse assembler.

The SCP loop rebuilds one such program per iteration with the same sparsity pattern;
``SparseAssembler`` makes that rebuild a single vectorized scatter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

_INT32_MAX = np.iinfo(np.int32).max


@dataclass(frozen=True)
class ConeSpec:
    """Row layout of the cone K: equalities, then nonnegatives, then each SOC block in order."""

    n_zero: int
    n_nonneg: int
    soc_dims: tuple[int, ...] = ()

    @property
    def n_rows(self) -> int:
        """Total number of rows of A (and entries of b) the cone covers."""
        return self.n_zero + self.n_nonneg + sum(self.soc_dims)

    def soc_starts(self) -> NDArray[np.int64]:
        """First row of each SOC block (the row holding the cone's ``t`` component)."""
        dims = np.asarray(self.soc_dims, dtype=np.int64)
        return self.n_zero + self.n_nonneg + np.cumsum(dims) - dims

    def validate(self) -> None:
        """Raise ValueError if a count is negative or an SOC block has dimension below 2."""
        if self.n_zero < 0 or self.n_nonneg < 0:
            raise ValueError(
                f"cone counts must be >= 0, got n_zero={self.n_zero}, n_nonneg={self.n_nonneg}"
            )
        bad = [d for d in self.soc_dims if d < 2]
        if bad:
            raise ValueError(
                f"SOC blocks need dimension >= 2 (a 1-D cone is a nonnegative row), got {bad}"
            )


@dataclass
class ConeProblem:
    """minimize 0.5 x'Px + q'x  subject to  A x + s = b, s in K  (Clarabel's standard form).

    ``P`` holds the upper triangle only (``None`` for a linear objective).
    """

    P: sp.csc_matrix | None
    q: NDArray[np.float64]
    A: sp.csc_matrix
    b: NDArray[np.float64]
    cones: ConeSpec

    @property
    def n(self) -> int:
        """Number of decision variables."""
        return int(np.shape(self.q)[0])

    @property
    def m(self) -> int:
        """Number of constraint rows."""
        return int(np.shape(self.b)[0])

    def validate_values(self) -> None:
        """Raise ValueError if q or b is not 1-D or q, b, A or P holds a non-finite value.

        The cheap part of ``validate``, for a problem whose structure (shapes, formats, cones,
        sparsity patterns) is known to equal that of an already validated one.
        """
        q = np.asarray(self.q)
        b = np.asarray(self.b)
        if q.ndim != 1:
            raise ValueError(f"q must be 1-D, got shape {q.shape}")
        if b.ndim != 1:
            raise ValueError(f"b must be 1-D, got shape {b.shape}")
        arrays = [("q", q), ("b", b), ("A.data", self.A.data)]
        if self.P is not None:
            arrays.append(("P.data", self.P.data))
        for name, values in arrays:
            if not np.isfinite(values).all():
                raise ValueError(f"{name} contains non-finite values")

    def validate(self) -> None:
        """Raise ValueError naming the first shape, format or finiteness problem found."""
        self.cones.validate()
        q = np.asarray(self.q)
        b = np.asarray(self.b)
        if q.ndim != 1:
            raise ValueError(f"q must be 1-D, got shape {q.shape}")
        if b.ndim != 1:
            raise ValueError(f"b must be 1-D, got shape {b.shape}")
        n, m = q.shape[0], b.shape[0]
        if not (sp.issparse(self.A) and self.A.format == "csc"):
            raise ValueError("A must be a scipy.sparse CSC matrix")
        if self.A.shape != (m, n):
            raise ValueError(f"A has shape {self.A.shape}, expected (len(b), len(q)) = {(m, n)}")
        if self.cones.n_rows != m:
            raise ValueError(f"cones cover {self.cones.n_rows} rows but b has {m}")
        for name, values in (("q", q), ("b", b), ("A.data", self.A.data)):
            if not np.all(np.isfinite(values)):
                raise ValueError(f"{name} contains non-finite values")
        if self.P is not None:
            P = self.P
            if not (sp.issparse(P) and P.format == "csc"):
                raise ValueError("P must be a scipy.sparse CSC matrix or None")
            if P.shape != (n, n):
                raise ValueError(f"P has shape {P.shape}, expected {(n, n)}")
            if not np.all(np.isfinite(P.data)):
                raise ValueError("P.data contains non-finite values")
            cols = np.repeat(np.arange(n), np.diff(P.indptr))
            if np.any(P.indices > cols):
                raise ValueError("P must hold the upper triangle only (row <= col)")


def same_pattern(a: sp.csc_matrix | None, b: sp.csc_matrix | None) -> bool:
    """True when two CSC matrices (or two Nones) have identical shape, indptr and indices."""
    if a is None or b is None:
        return a is None and b is None
    return (
        a.shape == b.shape
        and np.array_equal(a.indptr, b.indptr)
        and np.array_equal(a.indices, b.indices)
    )


class SparseAssembler:
    """Fixed-pattern CSC assembly: structure computed once, triplet values scattered per call.

    Duplicate (row, col) triplets are summed; entries whose value is zero stay explicit, so every
    assembled matrix has exactly the same indptr/indices (a backend can then update data only).
    """

    def __init__(
        self,
        rows: ArrayLike,
        cols: ArrayLike,
        shape: tuple[int, int],
        *,
        upper_triangular: bool = False,
    ) -> None:
        """Precompute the CSC structure of the triplets (rows[k], cols[k]) in a matrix of ``shape``.

        With ``upper_triangular`` (for P) any triplet below the diagonal raises ValueError.
        """
        r = np.asarray(rows, dtype=np.int64).ravel()
        c = np.asarray(cols, dtype=np.int64).ravel()
        n_rows, n_cols = int(shape[0]), int(shape[1])
        if r.shape != c.shape:
            raise ValueError(f"rows and cols differ in length: {r.size} vs {c.size}")
        if n_rows < 0 or n_cols < 0:
            raise ValueError(f"shape must be non-negative, got {shape}")
        if r.size and (r.min() < 0 or r.max() >= n_rows or c.min() < 0 or c.max() >= n_cols):
            raise ValueError(f"triplet index out of bounds for shape {shape}")
        if upper_triangular and np.any(r > c):
            raise ValueError("upper_triangular assembler got a triplet below the diagonal")

        order = np.lexsort((r, c))  # column-major, rows ascending within a column
        r_sorted, c_sorted = r[order], c[order]
        starts = np.ones(r.size, dtype=bool)
        starts[1:] = (r_sorted[1:] != r_sorted[:-1]) | (c_sorted[1:] != c_sorted[:-1])
        slot_sorted = np.cumsum(starts) - 1
        slot = np.empty(r.size, dtype=np.int64)
        slot[order] = slot_sorted

        nnz = int(starts.sum())
        big = max(nnz, n_rows, n_cols) > _INT32_MAX
        index_dtype = np.int64 if big else np.int32
        self._shape = (n_rows, n_cols)
        self._n_triplets = int(r.size)
        self._nnz = nnz
        self._slot = slot
        self._has_duplicates = nnz < r.size
        self._indices = r_sorted[starts].astype(index_dtype)
        counts = np.bincount(c_sorted[starts], minlength=n_cols)
        self._indptr = np.concatenate(([0], np.cumsum(counts))).astype(index_dtype)

    @property
    def shape(self) -> tuple[int, int]:
        """Shape of every assembled matrix."""
        return self._shape

    @property
    def nnz(self) -> int:
        """Number of stored entries (distinct (row, col) pairs, zeros included)."""
        return self._nnz

    @property
    def n_triplets(self) -> int:
        """Number of triplet values ``assemble`` expects."""
        return self._n_triplets

    @property
    def has_duplicates(self) -> bool:
        """True when some (row, col) pair occurs in more than one triplet (values are summed)."""
        return self._has_duplicates

    @property
    def positions(self) -> NDArray[np.int64]:
        """Index into the CSC data vector of each triplet (read-only view)."""
        view = self._slot.view()
        view.flags.writeable = False
        return view

    def matrix(self, data: NDArray[np.float64]) -> sp.csc_matrix:
        """The CSC matrix on this pattern with data vector ``data`` (used as is, not copied)."""
        if data.shape != (self._nnz,):
            raise ValueError(f"expected {self._nnz} data values, got shape {data.shape}")
        matrix = sp.csc_matrix(
            (data, self._indices.copy(), self._indptr.copy()), shape=self._shape, copy=False
        )
        matrix.has_canonical_format = True
        return matrix

    def assemble_data(self, values: ArrayLike) -> NDArray[np.float64]:
        """CSC data vector for triplet ``values`` (duplicates summed), in pattern order."""
        v = np.asarray(values, dtype=np.float64).ravel()
        if v.size != self._n_triplets:
            raise ValueError(f"expected {self._n_triplets} values, got {v.size}")
        if self._has_duplicates:
            summed = np.bincount(self._slot, weights=v, minlength=self._nnz)
            return summed.astype(np.float64, copy=False)
        data = np.empty(self._nnz, dtype=np.float64)
        data[self._slot] = v
        return data

    def assemble(self, values: ArrayLike) -> sp.csc_matrix:
        """Return the CSC matrix for triplet ``values``; its pattern never depends on the values."""
        return self.matrix(self.assemble_data(values))
