"""Whitening on the samples as stamped: jittered stamps, missing frames, masked samples,
and a noise derived from another recorder's through a known linear map.

Why: the stationary whiteners (:class:`~.model.Whitener`, :class:`~.filtered.LevinsonWhitener`)
assume one sample interval and a gap-free run; a recorder that jitters or drops frames,
and the ROCOF derived from such a recording (whose filter then differs from sample to
sample, :func:`rapid_cosim.simulator.rocof.rocof_operator`), break both assumptions. Here
the residual's noise is a linear state-space model over the record's samples:

    y_i = p(t_i) + w_i + sum_j M[i, j] f_j

``p``: the recorder's Ornstein-Uhlenbeck components, ``w`` its white part, both at the
true stamps; ``f``: the other recorder's noise (white + OU, at its own stamps, which are
the record's) seen through the rows of ``M`` (the derived ROCOF's map, scale included).
The state holds the OU values and the window of ``f`` samples that any row of ``M``
reaches, so the Kalman filter is exact. Its innovations, standardised, are a linear map
``e = W y`` with ``W`` lower triangular; since the filter forgets (it is stable), each row
of ``W`` is kept to the coefficients above ``TOL`` (the Levinson whitener truncates its
order the same way), and a batch is whitened by one sparse product (:mod:`.band`'s,
scipy's numbers computed quicker, where each row is a run of columns). Built once per
noise model and set of samples (a few tens of ms); the tests check it against the dense
Cholesky factor of the exact covariance, and against the stationary whiteners on a
regular grid.
"""

from __future__ import annotations

import functools
import hashlib
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import sparse

from .band import Band, product
from .filtered import FilteredNoise
from .model import RecorderNoise

TOL = 1e-12  # coefficients of the state's prediction below this are dropped (they only shrink)


@dataclass(frozen=True, eq=False)
class DerivedNoise(FilteredNoise):
    """Another recorder's noise through a sparse linear map on the record's own samples:
    ``matrix`` (n x n, scale included) maps the source noise at ``time`` to this noise at
    the same samples. ``taps`` (inherited) are the map's stationary form on the nominal
    grid, for what needs a stationary description (its sigma, the Levinson whitener of a
    model without sample times)."""

    time: np.ndarray = field(default=None, repr=False)
    matrix: sparse.csr_matrix = field(default=None, repr=False)

    @functools.cached_property
    def key(self) -> bytes:
        """A digest of what the noise is: equal digests, equal noises (whiteners are
        cached by it)."""
        m = self.matrix
        h = hashlib.blake2b(digest_size=16)
        for a in (self.time, m.data, m.indices, m.indptr, np.array(self.source.log_parameters()),
                  np.array([self.source.dt, len(self.source.components), self.source.sigma_white])):
            h.update(np.ascontiguousarray(a).tobytes())
        return h.digest() + hashlib.blake2b(np.asarray(self.taps).tobytes(), digest_size=8).digest()

    def __eq__(self, other) -> bool:
        return isinstance(other, DerivedNoise) and self.key == other.key

    def __hash__(self) -> int:
        return hash(self.key)

    def sample_rows(self, rows: np.ndarray, rng: np.random.Generator, size: int) -> np.ndarray:
        """``(size, len(rows))`` draws at those samples, exactly: the source drawn at its
        stamps, then mapped."""
        cols = np.unique(self.matrix[rows].indices)
        if cols.size == 0:
            return np.zeros((size, len(rows)))
        f = np.zeros((size, self.time.size))
        span = slice(int(cols[0]), int(cols[-1]) + 1)
        f[:, span] = self.source.sample(self.time[span], rng, size)
        return np.asarray((self.matrix[rows] @ f.T).T)


def regular(times: np.ndarray) -> bool:
    """One interval between every pair of neighbours, to 1 % (rounded stamps): where the
    stationary whiteners are exact."""
    if times.size < 3:
        return True
    steps = np.diff(times)
    dt = float(np.median(steps))
    return bool(np.max(np.abs(steps - dt)) <= 0.01 * dt)


@dataclass(eq=False)
class TimedWhitener:
    """The exact innovations map of :data:`model` (and ``derived``, at ``rows`` of its
    map) on samples at ``times`` (module docstring). ``W`` whitens (n, n) sparse,
    ``s`` holds each sample's innovation variance."""

    model: RecorderNoise  # the recorder's own part (its filtered components are ignored here)
    times: np.ndarray
    derived: DerivedNoise | None = None
    rows: np.ndarray | None = None  # the samples' rows of derived's map
    W: sparse.csr_matrix = field(init=False, repr=False)
    s: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        self.times = np.asarray(self.times, dtype=float)
        if self.derived is None:
            grid, observed = self.times, np.arange(self.times.size)
            H_f, lag_lo, L, src = None, 0, 0, None
        else:
            grid = self.derived.time
            observed = np.asarray(self.rows, dtype=np.int64)
            sub = self.derived.matrix[observed].tocoo()
            offsets = sub.col - observed[sub.row]
            lag_lo, lag_hi = (int(offsets.min()), int(offsets.max())) if sub.nnz else (0, 0)
            L = lag_hi - lag_lo + 1
            H_f = np.zeros((observed.size, L))
            H_f[sub.row, sub.col - observed[sub.row] - lag_lo] = sub.data
            src = self.derived.source
        self.W, self.s = _kalman_map(self.model, grid, observed, H_f, lag_lo, L, src)
        self._band = Band.of(self.W)  # its rows are runs of columns: band.c's product, scipy's numbers

    def whiten(self, r: np.ndarray) -> np.ndarray:
        """Standardised innovations of residual rows ``r`` (rows, n)."""
        return product(self.W, self._band, np.atleast_2d(np.asarray(r, dtype=float)))

    def log_det(self) -> float:
        return float(np.sum(np.log(self.s)))


def _stamps(grid: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Times of sample indices, extended past both ends on the median step."""
    dt = float(np.median(np.diff(grid))) if grid.size > 1 else 1.0
    i = np.asarray(index)
    inside = np.clip(i, 0, grid.size - 1)
    return np.where(i < 0, grid[0] + i * dt, np.where(i >= grid.size, grid[-1] + (i - grid.size + 1) * dt,
                                                         grid[inside]))


def _ou_cov(t: np.ndarray, comps, white: float) -> np.ndarray:
    lag = np.abs(np.subtract.outer(t, t))
    cov = sum(s * s * np.exp(-lag / tau) for s, tau in comps) if comps else np.zeros_like(lag)
    return cov + white ** 2 * np.eye(t.size)


def _kalman_map(model: RecorderNoise, grid, observed, H_f, lag_lo: int, L: int,
                src: RecorderNoise | None) -> tuple[sparse.csr_matrix, np.ndarray]:
    """Run the filter over ``grid`` (every sample from the first observed one; innovations
    at ``observed`` ones), tracking the prediction's coefficients on past observations;
    returns (W, s)."""
    comps = list(model.components)
    kp = len(comps)
    fcomps = list(src.components) if (src is not None and L) else []
    kf = len(fcomps)
    d = kp + L + kf
    n = observed.size
    if n == 0:
        return sparse.csr_matrix((0, 0)), np.zeros(0)
    if d == 0:  # white noise alone
        return sparse.identity(n, format="csr") / model.sigma_white, np.full(n, model.sigma_white ** 2)
    first, last = int(observed[0]), int(observed[-1])
    F, Q, P = _system(grid, first, last, comps, fcomps, L, lag_lo, src)
    white2 = model.sigma_white ** 2
    H = np.zeros((n, d))
    H[:, :kp] = 1.0
    if L:
        H[:, kp:kp + L] = H_f
    at = observed - first  # the step of each observation
    G = np.zeros((d, 0))  # the state prediction's coefficients on past observations, newest first
    data, cols, s_out = [], [], np.empty(n)
    indptr = np.zeros(n + 1, dtype=np.int64)
    k = 0
    for j in range(last - first + 1):
        if at[k] == j:
            h = H[k]
            PH = P @ h
            S = float(h @ PH) + white2
            HG = h @ G
            root = math.sqrt(S)
            data.append(np.concatenate((-HG[::-1] / root, (1.0 / root,))))
            cols.append(np.arange(k - HG.size, k + 1))
            indptr[k + 1] = indptr[k] + HG.size + 1
            s_out[k] = S
            K = PH / S
            G = np.concatenate((K[:, None], G - K[:, None] * HG), axis=1)
            P = P - np.outer(K, PH)
            k += 1
            if k == n:
                break
        G = F[j] @ G
        P = F[j] @ P @ F[j].T + Q[j]
        if G.shape[1] > 1 and np.abs(G[:, -1]).max() < TOL:
            big = np.flatnonzero(np.abs(G).max(axis=0) >= TOL)
            G = G[:, :big[-1] + 1] if big.size else G[:, :0]
    W = sparse.csr_matrix((np.concatenate(data), np.concatenate(cols), indptr), shape=(n, n))
    return W, s_out


def _system(grid, first: int, last: int, comps, fcomps, L: int, lag_lo: int, src):
    """Per step from ``first`` to ``last``: the transitions F and process noises Q of the
    state (OU of the recorder, the window of the source's samples, the source's OU at the
    window's newest sample), and the stationary prior at ``first``."""
    kp, kf = len(comps), len(fcomps)
    d = kp + L + kf
    m = last - first + 1
    F = np.zeros((m, d, d))
    Q = np.zeros((m, d, d))
    P = np.zeros((d, d))
    if kp:
        t_p = _stamps(grid, np.arange(first, last + 2))
        sig = np.array([s for s, _ in comps])
        a = np.exp(-np.diff(t_p)[:, None] / np.array([tau for _, tau in comps])[None, :])
        diag = np.arange(kp)
        F[:, diag, diag] = a
        Q[:, diag, diag] = sig ** 2 * (1.0 - a * a)
        P[diag, diag] = sig ** 2
    if L:
        t_f = _stamps(grid, np.arange(first + lag_lo, last + lag_lo + L + 1))
        P[kp:kp + L, kp:kp + L] = _ou_cov(t_f[:L], fcomps, src.sigma_white)
        F[:, kp:kp + L - 1, kp + 1:kp + L] = np.eye(L - 1)  # the window of f shifts by one sample
        newest, z0 = kp + L - 1, kp + L
        Q[:, newest, newest] = src.sigma_white ** 2
        if kf:
            sig = np.array([s for s, _ in fcomps])
            tau = np.array([t for _, t in fcomps])
            for c in range(kf):
                cross = sig[c] ** 2 * np.exp(-np.abs(t_f[L - 1] - t_f[:L]) / tau[c])
                P[z0 + c, kp:kp + L] = P[kp:kp + L, z0 + c] = cross
                P[z0 + c, z0 + c] = sig[c] ** 2
            b = np.exp(-np.diff(t_f)[L - 1:, None] / tau[None, :])  # (m, kf)
            q = sig ** 2 * (1.0 - b * b)
            diag = np.arange(z0, z0 + kf)
            F[:, diag, diag] = b
            F[:, newest, z0:] = b  # the new f sample: its OU parts plus new white noise
            Q[:, newest, newest] += q.sum(axis=1)
            Q[:, newest, z0:] = q
            Q[:, z0:, newest] = q
            Q[:, diag, diag] = q
    return F, Q, P


def dense_covariance(model: RecorderNoise, times: np.ndarray, derived: DerivedNoise | None = None,
                     rows: np.ndarray | None = None) -> np.ndarray:
    """The exact covariance of the samples (small cases: what the tests check against)."""
    cov = _ou_cov(np.asarray(times, dtype=float), list(model.components), model.sigma_white)
    if derived is not None:
        M = derived.matrix[np.asarray(rows)].toarray()
        src = derived.source
        cov = cov + M @ _ou_cov(derived.time, list(src.components), src.sigma_white) @ M.T
    return cov
