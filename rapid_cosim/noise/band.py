"""The exact whitener's sparse product, computed by ``band.c``: the numbers of scipy's
CSR product bit for bit, 1.3 to 1.9 times quicker on the batches a fit and the adequacy
null whiten (1 to 1,000 residual rows); several rows at a time (8 to 300 measured) about
twice as quick again where the processor has AVX-512 (:func:`ways`; ``make bench``'s
``whitening`` section). The stationary whiteners' triangular maps use it too
(:class:`Triangular`): it sums each row in one order whatever the rows beside it.

Why it may replace scipy's product: every output element is the same sum in the same
order (``band.c`` says how), and the library is checked against scipy's product on this
machine, on a random band of every shape the kernel treats differently, before it is
used (:func:`library`); where it differs, or no C compiler is found, scipy's product is
used, with a warning.
"""

from __future__ import annotations

import ctypes
import functools
import warnings
from pathlib import Path

import numpy as np
from scipy import sparse

SOURCE = Path(__file__).with_name("band.c")
_P = ctypes.c_void_p


class Band:
    """A CSR matrix whose rows are each a contiguous run of columns, held as each run's
    first column with the CSR's row pointers and coefficients (:meth:`of`)."""

    def __init__(self, n: int, ptr: np.ndarray, first: np.ndarray, data: np.ndarray):
        self.n = n
        self.ptr = np.ascontiguousarray(ptr, dtype=np.int64)
        self.first = np.ascontiguousarray(first, dtype=np.int32)
        self.data = np.ascontiguousarray(data, dtype=float)

    @staticmethod
    def of(W: sparse.csr_matrix) -> "Band | None":
        """``W`` as a band, or None where it is not one (a row's columns not a
        contiguous increasing run, or no coefficients) or not square."""
        if W.shape[0] != W.shape[1] or W.nnz == 0:
            return None
        lengths = np.diff(W.indptr)
        first = np.where(lengths > 0, W.indices[np.minimum(W.indptr[:-1], W.nnz - 1)], 0)
        if not np.array_equal(W.indices, np.repeat(first, lengths) + np.arange(W.nnz) - np.repeat(W.indptr[:-1], lengths)):
            return None
        return Band(W.shape[0], W.indptr, first, W.data)

    def apply(self, r: np.ndarray, lib: ctypes.CDLL) -> np.ndarray:
        """``(W @ r.T).T`` for residual rows ``r`` (rows, n), laid out as that is (the
        transpose of a C-ordered (n, rows) array): the same numbers, the same memory order."""
        self._check(r)
        if r.shape[0] == 1:
            y, e = np.ascontiguousarray(r[0], dtype=float), np.empty(self.n)
            lib.rc_band_row(self.n, *self._args(), y.ctypes.data, e.ctypes.data)
            return e[None, :]
        return self._rows(lib.rc_band_rows, r)

    def rows_by(self, lib: ctypes.CDLL, way: int, r: np.ndarray) -> np.ndarray:
        """:meth:`apply` for several rows by the kernel's way ``way`` (a bit of
        :data:`WAYS`), not necessarily the one this processor takes (one it has not is
        taken by the pairs), so that each way can be checked."""
        self._check(r)
        return self._rows(functools.partial(lib.rc_band_rows_by, way), r)

    def _check(self, r: np.ndarray) -> None:
        if r.ndim != 2 or r.shape[1] != self.n:
            raise ValueError(f"dimension mismatch: residual rows of {r.shape[-1]} samples against a whitener of "
                             f"{self.n}")

    def _args(self) -> tuple:
        return self.ptr.ctypes.data, self.first.ctypes.data, self.data.ctypes.data

    def _rows(self, kernel, r: np.ndarray) -> np.ndarray:
        """Several rows through ``kernel`` (rc_band_rows's arguments), on their transpose."""
        xT = np.ascontiguousarray(r.T, dtype=float)
        eT = np.empty_like(xT)
        kernel(xT.shape[1], self.n, *self._args(), xT.ctypes.data, eT.ctypes.data)
        return eT.T


def product(W: sparse.csr_matrix, band: "Band | None", r: np.ndarray) -> np.ndarray:
    """``(W @ r.T).T``: by the band kernel where ``W`` is a band and the kernel is checked."""
    lib = library() if band is not None else None
    if lib is not None:
        return band.apply(r, lib)
    return np.asarray((W @ r.T).T)


class Triangular:
    """A dense lower-triangular map (a stationary whitener's first ``m`` samples) applied
    to residual rows by the same product: each output summed along its row in one order,
    however many rows come with it (BLAS takes one row by ``gemv`` and several by
    ``gemm``, in other orders, so a set's score depended on its batch). Every entry on
    and below the diagonal is kept, zeros too, so each row is one run of columns from the
    first, and the map of a shorter run (its first ``n`` rows and columns) is a prefix
    of the coefficients. Made for every noise model a REML fit tries, so only the
    coefficients are gathered here."""

    def __init__(self, W: np.ndarray):
        self.m = W.shape[0]
        rows, cols, self._ptr = _lower(self.m)
        self._data = np.ascontiguousarray(W[rows, cols], dtype=float)
        self._bands: dict[int, Band] = {}

    def apply(self, y: np.ndarray) -> np.ndarray:
        """``y @ W[:n, :n].T`` for rows ``y`` (rows, n), n <= m."""
        n = y.shape[1]
        if n == 0:
            return np.zeros((y.shape[0], 0))
        band = self._bands.get(n)
        if band is None:
            band = self._bands[n] = Band(n, self._ptr[:n + 1], np.zeros(n, dtype=np.int32), self._data[:self._ptr[n]])
        # scipy's matrix only where product() needs it (no kernel here): the same numbers
        W = None if library() is not None else sparse.csr_matrix((band.data, _lower(n)[1], band.ptr), shape=(n, n))
        return np.ascontiguousarray(product(W, band, np.asarray(y, dtype=float)))


@functools.lru_cache(maxsize=32)
def _lower(m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rows, columns and CSR row pointers of the entries on and below the diagonal
    of an ``m`` x ``m`` matrix, row by row."""
    rows, cols = np.tril_indices(m)
    return rows, cols.astype(np.int32), np.concatenate([[0], np.cumsum(np.arange(1, m + 1))]).astype(np.int64)


@functools.lru_cache(maxsize=1)
def library() -> ctypes.CDLL | None:
    """The kernel, built once per machine and loaded once per process; None (scipy's
    product then) where it cannot be built or does not give scipy's numbers here."""
    from ..compiler.embedded import shared_library
    from ..errors import BuildError

    try:
        lib = ctypes.CDLL(str(shared_library("rapid_cosim_band", (SOURCE,), (SOURCE,), ("-ffp-contract=off",),
                                             what="the whitener's band product")))
    except (BuildError, OSError) as e:
        warnings.warn(f"{str(e).splitlines()[0]}; residuals are whitened by scipy's sparse product "
                      "(the same numbers, slower)", stacklevel=2)
        return None
    lib.rc_band_rows.argtypes = [ctypes.c_int, ctypes.c_int, _P, _P, _P, _P, _P]
    lib.rc_band_rows_by.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int, _P, _P, _P, _P, _P]
    lib.rc_band_row.argtypes = [ctypes.c_int, _P, _P, _P, _P, _P]
    lib.rc_band_rows.restype = lib.rc_band_rows_by.restype = lib.rc_band_row.restype = None
    lib.rc_band_ways.argtypes, lib.rc_band_ways.restype = [], ctypes.c_int
    if not _agrees(lib):
        warnings.warn("the whitener's band product does not give scipy's numbers on this machine; residuals "
                      "are whitened by scipy's sparse product", stacklevel=2)
        return None
    return lib


def _agrees(lib: ctypes.CDLL) -> bool:
    """The kernel against scipy's product, bit for bit, on a random band (rows of every
    length from 1, so the four-row groups end unevenly, and their heads and tails differ)
    for every block width it uses and across its passes of 128 residual rows, by every way
    this processor has (:data:`WAYS`), the one it takes included."""
    rng = np.random.default_rng(20261128)
    n = 203
    lengths = np.minimum(np.arange(n) + 1, rng.integers(30, 60, n))
    short = rng.random(n) < 0.15  # rows of 0 to 2 coefficients: four rows with no common run, empty ones
    lengths[short] = np.minimum(np.arange(n)[short] + 1, rng.integers(0, 3, int(short.sum())))
    rows = np.repeat(np.arange(n), lengths)
    cols = np.concatenate([np.arange(i - k + 1, i + 1) for i, k in enumerate(lengths)])
    W = sparse.csr_matrix((rng.standard_normal(rows.size), (rows, cols)), shape=(n, n))
    band = Band.of(W)
    if band is None:
        return False
    for m in (*range(1, 34), 40, 64, 86, 130, 300):  # every tile width and last vector's lanes
        r = rng.standard_normal((m, n)) * 10.0 ** rng.integers(-6, 3, (m, 1))
        expected = np.asarray((W @ r.T).T)
        if not np.array_equal(band.apply(r, lib), expected):
            return False
        if m > 1 and not all(np.array_equal(band.rows_by(lib, way, r), expected) for way in _ways(lib)):
            return False
    return True


WAYS = {1: "pairs of lanes", 2: "AVX2", 4: "AVX-512"}  # rc_band_ways's bits, widest last


def _ways(lib: ctypes.CDLL) -> list[int]:
    return [bit for bit in WAYS if lib.rc_band_ways() & bit]


def ways() -> list[str]:
    """The ways this processor can whiten several residual rows (the kernel takes the
    last): pairs of lanes on any processor; four rows of the band at a time in AVX2 or
    AVX-512 vectors where it has them. Empty where the kernel is not used."""
    lib = library()
    return [WAYS[bit] for bit in _ways(lib)] if lib is not None else []
