"""What every whitener of a run of samples shares, and the runs of a mask: a leaf of
:mod:`rapid_cosim.noise` that imports nothing from the package, so the stationary
whiteners (:mod:`.model`) and the autocovariance one (:mod:`.filtered`) both build on
it without importing each other.

No product of residual rows in :mod:`rapid_cosim.noise` goes to BLAS: BLAS sums a row
in an order that depends on the rows that come with it (one row goes to ``dot`` or
``gemv``, several to ``gemm``), so the same parameter set scored alone and in a batch
differed in its last bits, and with it an optimiser's path on one worker and on two.
Thin products (a vector, a state of one or two components) go through :func:`rowwise`;
the whiteners' triangular maps through :class:`~.band.Triangular`."""

from __future__ import annotations

import numpy as np


class RunWhitening:
    """What every whitener shares once it has ``m``, ``s``, ``s_inf`` and
    ``whiten_runs``: the variances, the unscaled innovations, gaps, the log-determinant."""

    m: int
    s: np.ndarray
    s_inf: float

    def variances(self, n: int) -> np.ndarray:
        """Innovation variances of the first ``n`` samples of a run."""
        if n <= self.m:
            return self.s[:n] if self.m else np.full(n, self.s_inf)
        return np.concatenate([self.s, np.full(n - self.m, self.s_inf)])

    def innovations(self, y: np.ndarray) -> np.ndarray:
        """Unscaled innovations of runs ``y`` (rows, n) with no gap, each from the
        stationary prior."""
        y = np.asarray(y, dtype=float)
        return self.whiten_runs(y).reshape(y.shape) * np.sqrt(self.variances(y.shape[-1]))

    def whiten_runs(self, y: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def whiten_masked(self, residual: np.ndarray) -> np.ndarray:
        r = np.asarray(residual, dtype=float)
        one = r.ndim == 1
        r2 = r[None] if one else r
        out = np.full(r2.shape, np.nan)
        valid = np.all(np.isfinite(r2), axis=0)  # a batch shares its mask
        for start, stop in runs(valid):
            out[:, start:stop] = self.whiten_runs(r2[:, start:stop])
        return out[0] if one else out

    def log_det(self, n: int) -> float:
        """log |Cov| of a gap-free run of ``n`` samples."""
        return float(np.sum(np.log(self.variances(n))))


def rowwise(y: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``y @ A.T`` for rows ``y`` (rows, n) and ``A`` (k, n) or a vector (n,): each
    output summed over ``n`` in one order, whatever the rows beside it (numpy's einsum
    loop over C-ordered rows, not BLAS: on a transposed layout it sums in another order)."""
    return np.einsum("rj,kj->rk" if np.ndim(A) == 2 else "rj,j->r", np.ascontiguousarray(y),
                     np.ascontiguousarray(A))


def runs(valid: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of each run of consecutive True values."""
    v = np.concatenate([[False], np.asarray(valid, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(v.astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))
