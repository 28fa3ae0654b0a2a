"""ROCOF from a recorded frequency: the input ``rocof`` (Hz/s) of the recorded-frequency
benches, when the recording has no ROCOF channel.

Why a filter, and this one: the electrical power a plant records carries the rotor's
inertial power 2 H (df/dt) / f_nom, so the bench needs df/dt. A plain difference of a
1 mHz-noise frequency at 50 frames/s is noise of 0.07 Hz/s, +-0.02 pu on 2H = 13 s. The
whole record is known, so the filter can be zero-phase: a Savitzky-Golay derivative (the
slope of a least-squares quadratic over a centred window, A. Savitzky and M. J. E. Golay,
Anal. Chem. 36 (1964) 1627). It has no delay, and it is exact for any frequency that is
quadratic over the window, so a smooth excursion's ROCOF is not biased: only content
faster than the window is lost (the default 0.3 s window at 50 frames/s passes 0.98 of
0.5 Hz, 0.82 of 1.5 Hz and 0.69 of 2 Hz, see :func:`gain`); a step of ROCOF (a load
switched) is spread over the window, half of it before the step. A PMU cannot look ahead: an IEEE C37.118.1 P-class
unit estimates ROCOF over two cycles with no further filter, an M-class unit filters
causally with a measurement bandwidth of min(Fs/5, 5 Hz) and the delay that costs. This
filter is band-limited as an M-class unit (narrower: it is tuned to the electromechanical
band, 0.1 to 2 Hz) without its delay; it is not a C37.118 estimator.

Its noise: white frequency noise sigma_f gives ROCOF noise sigma_f x :func:`noise_gain`
(2.99 / s at 50 frames/s and 0.3 s: 1 mHz of white noise -> 3.0 mHz/s, 7.8e-4 pu on
2H = 13 s; a PMU's correlated frequency noise gives less);
the experiment layer measures it on the quiet pre-event samples and adds it to the
fitness's noise (:mod:`rapid_cosim.experiment.electrical`).

Stamps as recorders write them: the local fits are made on the actual time stamps
(:func:`rocof_operator`), so jitter and missing frames change only which samples a window
holds and where they lie, never the filter's meaning; there is no fallback to a raw
difference. A window that cannot hold a fit is named, and the experiment leaves the
power samples that depend on it out of its fit. Tables with steps (a time written twice)
are derived piecewise: a step's impulse is not representable, and each side gets the
derivative of its own samples.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.signal import savgol_coeffs

from .inputs import InputTable

ROCOF = "rocof"  # the benches' ROCOF input (Hz/s)
FREQUENCY = "f_dev"  # the benches' frequency input (Hz, deviation from f_nom)
WINDOW = 0.3  # s: the default Savitzky-Golay window
ORDER = 2  # the local polynomial (a quadratic: its slope is a linear fit's over a symmetric window)
MIN_SPAN = 3  # steps: a window holds a fit with ORDER + 2 valid samples spanning at least this many


def points(dt: float, window: float = WINDOW) -> int:
    """Samples in the window: odd, at least ORDER + 3."""
    n = int(round(window / dt))
    n += 1 - n % 2
    return max(n, ORDER + 3 if (ORDER + 3) % 2 else ORDER + 4)


def derive_rocof(time: np.ndarray, values: np.ndarray, window: float = WINDOW,
                 breaks: tuple[float, ...] = (), valid: np.ndarray | None = None) -> np.ndarray:
    """d(values)/dt on ``time``: :func:`rocof_operator`'s local quadratic slopes (the
    zero-phase Savitzky-Golay derivative where the stamps are regular), over the valid
    samples only; a sample whose window cannot hold a fit gets the slope interpolated from
    its neighbours' (:class:`RocofOperator` says which)."""
    return rocof_operator(time, window, breaks, valid).apply(values)


@dataclass(frozen=True, eq=False)
class RocofOperator:
    """The ROCOF as a linear map of the recorded frequency: ``rocof = matrix @ f`` on the
    frequency's own samples (columns of masked samples are zero), and the rows whose
    window could not hold a fit (``unfit``: fewer than ORDER + 2 valid samples, or spanning
    fewer than MIN_SPAN steps). The same map gives the derived ROCOF's
    noise exactly (:mod:`rapid_cosim.experiment.electrical`)."""

    time: np.ndarray
    matrix: sparse.csr_matrix
    unfit: np.ndarray  # bool per row

    def apply(self, values: np.ndarray) -> np.ndarray:
        v = np.where(np.isfinite(values), values, 0.0)
        out = self.matrix @ v
        if self.unfit.any():
            ok = ~self.unfit
            if not ok.any():
                return np.zeros_like(out)
            out[self.unfit] = np.interp(self.time[self.unfit], self.time[ok], out[ok])
        return out

    def unfit_spans(self) -> list[tuple[float, float, int]]:
        """(first, last time, rows) of each run of rows with no fit."""
        edges = np.diff(np.concatenate([[0], self.unfit.view(np.int8), [0]]))
        return [(float(self.time[a]), float(self.time[b - 1]), int(b - a))
                for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1))]


def rocof_operator(time: np.ndarray, window: float = WINDOW, breaks: tuple[float, ...] = (),
                   valid: np.ndarray | None = None) -> RocofOperator:
    """:func:`_operator`, kept per stamps, window, breaks and valid samples: a diagnosis
    builds each test's inputs again for every candidate (157 operators of 4 ms each on the
    steam unit); the last 16, a unit's tests (about 200 bytes a sample each). Its arrays are
    read-only, as the operator is shared."""
    t = np.ascontiguousarray(time, dtype=float)
    v = None if valid is None else np.ascontiguousarray(valid, dtype=bool)
    return _kept(t.tobytes(), float(window), tuple(float(b) for b in np.atleast_1d(breaks)),
                 None if v is None else v.tobytes())


@functools.lru_cache(maxsize=16)
def _kept(time: bytes, window: float, breaks: tuple[float, ...], valid: bytes | None) -> RocofOperator:
    op = _operator(np.frombuffer(time), window, breaks, None if valid is None else np.frombuffer(valid, dtype=bool))
    op.matrix.data.flags.writeable = op.matrix.indices.flags.writeable = op.matrix.indptr.flags.writeable = False
    op.unfit.flags.writeable = False
    return op


def _operator(time: np.ndarray, window: float, breaks: tuple[float, ...],
              valid: np.ndarray | None) -> RocofOperator:
    """The local least-squares quadratic's slope at each sample, fitted on the samples as
    stamped (jittered, with frames missing), valid ones only, between steps and
    ``breaks``.

    A row's window is the nominal one: the samples within (points(dt) / 2) steps of the
    nominal step ``dt`` (the median step) either side, shifted inside its piece at the
    piece's ends. On regular stamps that is exactly the Savitzky-Golay derivative with
    ``mode="interp"``; on jittered ones each window keeps its samples and their true
    times; a missing frame is simply absent. A piece is cut at a time written twice (a
    table's step) and after the last sample at or before a break (a sample at a break's
    time was recorded as the event began, before the power moved: given the post-event
    slope instead, the bench's P_e stepped one sample early there, 0.05 pu against 0.002
    of noise on an ANDES event)."""
    t = np.asarray(time, dtype=float)
    n = t.size
    ok = np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool).copy()
    if n < 2:
        return RocofOperator(t, sparse.csr_matrix((n, n)), np.ones(n, dtype=bool))
    steps = np.diff(t)
    dt = float(np.median(steps[steps > 0])) if np.any(steps > 0) else 1.0
    half = (points(dt, window) - 1) // 2
    reach = (half + 0.5) * dt
    cuts = np.zeros(n, dtype=np.int64)  # piece number of each sample
    cut_at = set((np.flatnonzero(steps == 0) + 1).tolist())
    cut_at.update(int(i) for i in np.searchsorted(t, breaks, side="right") if 0 < i < n)
    for i in sorted(cut_at):
        cuts[i:] += 1
    first = np.searchsorted(cuts, cuts, side="left")  # each sample's piece: [first, last]
    last = np.searchsorted(cuts, cuts, side="right") - 1
    a = t - reach
    b = t + reach
    low = a < t[first] - 0.5 * dt  # shifted inside the piece at its ends
    a = np.where(low, t[first] - 0.5 * dt, a)
    b = np.where(low, t[first] - 0.5 * dt + 2 * reach, b)
    high = b > t[last] + 0.5 * dt
    b = np.where(high, t[last] + 0.5 * dt, b)
    a = np.where(high & ~low, t[last] + 0.5 * dt - 2 * reach, a)
    lo = np.maximum(np.searchsorted(t, a, side="left"), first)
    hi = np.minimum(np.searchsorted(t, b, side="right"), last + 1)
    width = int(np.max(hi - lo))
    idx = lo[:, None] + np.arange(width)[None, :]
    inside = idx < hi[:, None]
    idx = np.minimum(idx, n - 1)
    member = inside & ok[idx]
    u = np.where(member, (t[idx] - t[:, None]) / reach, 0.0)
    basis = np.stack([np.ones_like(u), u, u * u], axis=-1) * member[..., None]  # (n, width, 3)
    gram = np.einsum("nwi,nwj->nij", basis, basis)
    count = member.sum(axis=1)
    span = np.where(member, t[idx], np.inf).min(axis=1), np.where(member, t[idx], -np.inf).max(axis=1)
    unfit = (count < ORDER + 2) | (span[1] - span[0] < MIN_SPAN * dt)
    gram[unfit] = np.eye(3)
    slope = np.linalg.solve(gram, np.broadcast_to(np.array([0.0, 1.0, 0.0]), (n, 3))[..., None])[..., 0]
    coef = np.einsum("nwi,ni->nw", basis, slope) / reach
    coef[unfit] = 0.0
    keep = member & ~unfit[:, None]
    rows = np.broadcast_to(np.arange(n)[:, None], idx.shape)[keep]
    matrix = sparse.csr_matrix((coef[keep], (rows, idx[keep])), shape=(n, n))
    return RocofOperator(t, matrix, unfit)


def noise_gain(dt: float, window: float = WINDOW) -> float:
    """ROCOF noise (Hz/s) per unit of white frequency noise (Hz): the coefficients' norm."""
    return float(np.linalg.norm(savgol_coeffs(points(dt, window), ORDER, deriv=1, delta=dt)))


def gain(freq_hz: float, dt: float, window: float = WINDOW) -> float:
    """The filter's gain relative to the true derivative at a frequency (1 at DC)."""
    c = savgol_coeffs(points(dt, window), ORDER, deriv=1, delta=dt, use="dot")
    k = np.arange(c.size) - c.size // 2
    w = 2 * np.pi * freq_hz
    return float(abs(np.sum(c * np.exp(1j * w * k * dt))) / w)


def with_rocof(table: InputTable, window: float = WINDOW, breaks: tuple[float, ...] = ()) -> InputTable:
    """``table`` with ``rocof`` derived from ``f_dev`` (unchanged if it has one or no f_dev)."""
    if ROCOF in table.names or FREQUENCY not in table.names:
        return table
    f = table.values[:, table.names.index(FREQUENCY)]
    return InputTable(table.time, table.names + (ROCOF,),
                      np.column_stack([table.values, derive_rocof(table.time, f, window, breaks)]))


def without_rocof(table: InputTable) -> InputTable:
    """``table`` without its ROCOF column: a derived one offered to a model without the input."""
    keep = [k for k, n in enumerate(table.names) if n != ROCOF]
    return InputTable(table.time, tuple(table.names[k] for k in keep), table.values[:, keep])
