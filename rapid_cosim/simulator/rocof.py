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

Tables with steps (a time written twice) are derived piecewise: a step's impulse is not
representable, and each side gets the derivative of its own samples.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import savgol_coeffs, savgol_filter

from .inputs import InputTable

ROCOF = "rocof"  # the benches' ROCOF input (Hz/s)
FREQUENCY = "f_dev"  # the benches' frequency input (Hz, deviation from f_nom)
WINDOW = 0.3  # s: the default Savitzky-Golay window
ORDER = 2  # the local polynomial (a quadratic: its slope is a linear fit's over a symmetric window)


def points(dt: float, window: float = WINDOW) -> int:
    """Samples in the window: odd, at least ORDER + 3."""
    n = int(round(window / dt))
    n += 1 - n % 2
    return max(n, ORDER + 3 if (ORDER + 3) % 2 else ORDER + 4)


def derive_rocof(time: np.ndarray, values: np.ndarray, window: float = WINDOW,
                 breaks: tuple[float, ...] = ()) -> np.ndarray:
    """d(values)/dt on ``time`` by the zero-phase Savitzky-Golay derivative, piecewise
    between steps and at ``breaks`` (an event's known start: its ROCOF step is not spread
    over the samples before it, where the bench's P_e would otherwise swing ahead of the
    recording's); a piece too short or not evenly sampled gets second-order differences.
    A sample at a break's time ends the piece before it: it was recorded as the event
    began, before the power moved (given the post-event slope instead, the bench's P_e
    stepped one sample early there, 0.05 pu against 0.002 of noise on an ANDES event, and
    structure selection found every structure inadequate, variance ratio 1.7).

    Measured on the ANDES events (experiments/electrical, noise-free samples): the split,
    the window (0.15, 0.3 or 0.6 s) and ANDES's exact ROCOF instead of this one each move
    the fitted fast lag by at most 1.5 % and R by 0.3 %; a fast lag's larger errors there
    are the recorder noise's draw (tests/test_electrical.py)."""
    t = np.asarray(time, dtype=float)
    v = np.asarray(values, dtype=float)
    out = np.zeros_like(v)
    cuts = set((np.flatnonzero(np.diff(t) == 0) + 1).tolist())
    cuts.update(int(i) for i in np.searchsorted(t, breaks, side="right") if 0 < i < t.size)
    for seg in np.split(np.arange(t.size), sorted(cuts)):
        out[seg] = _piece(t[seg], v[seg], window)
    return out


def _piece(t: np.ndarray, v: np.ndarray, window: float) -> np.ndarray:
    if t.size < 2:
        return np.zeros_like(v)
    steps = np.diff(t)
    dt = float(np.median(steps))
    n = points(dt, window)
    if t.size < n or np.max(np.abs(steps - dt)) > 0.01 * dt:  # time stamps rounded, not jittered
        return np.gradient(v, t) if t.size > 2 else np.full_like(v, (v[-1] - v[0]) / (t[-1] - t[0]))
    return savgol_filter(v, n, ORDER, deriv=1, delta=dt, mode="interp")


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
