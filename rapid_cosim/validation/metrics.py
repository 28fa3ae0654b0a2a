"""Per-test error metrics of a calibrated model, as model-validation reports for a unit's
primary frequency response state them.

All are computed on the measured time base inside the fitness window, from the
measured output (converted as configured) and the simulation with its profiled offset.
The event is ``[fitness] pre_step_end`` (else the start of the window); the span judged
runs from it to the end of the window, or to a staged test's return step. "Smoothed"
means a centred moving mean over 1 s (shorter at the span's ends), so that a time is read
off the response and not off one noisy sample.

``rmse``
    root mean square of the residual.
``peak_error``
    the largest absolute residual (shown, not judged: one sample of noise sets it).
``settled_change`` (measured, simulated)
    the change of the output from its pre-event level (mean before the event) to its
    settled level (mean of the last 10 % of the span).
``peak_change`` (measured, simulated)
    the largest smoothed change from the pre-event level in the direction of the settled
    change (a hydro unit's initial inverse response is not its peak).
``rise_time`` (measured, simulated)
    from the event to the first smoothed sample that has covered 90 % of the settled
    change.
``time_to_peak`` (measured, simulated)
    from the event to the peak; given only when the measured response overshoots its
    settled change by more than 5 % of it and three noise levels (without an overshoot
    the peak is the settled level and its time is the noise's).
``settling_time`` (measured, simulated)
    from the event until the smoothed output stays within 5 % of the settled change (at
    least two noise levels) of its settled level; ``inf`` when it never does in the span.

Times are None when the measured change is under five noise levels: they would be the
noise's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


SETTLED_SHARE = 0.10
RESPONSE_LEVEL = 0.90
SMOOTHING_S = 1.0
MIN_CHANGE_IN_NOISE = 5.0
OVERSHOOT_SHARE = 0.05
OVERSHOOT_IN_NOISE = 3.0
SETTLING_SHARE = 0.05
SETTLING_IN_NOISE = 2.0

Pair = tuple[float | None, float | None]  # measured, simulated


@dataclass(frozen=True)
class ValidationMetrics:
    experiment: str
    output: str
    rmse: float
    peak_error: float
    settled_change: tuple[float, float]  # measured, simulated
    peak_change: tuple[float, float]
    rise_time: Pair  # s after the event
    time_to_peak: Pair
    settling_time: Pair
    noise: float | None  # the experiment's noise level, for scale
    role: str = "training"  # or "held out": predicted at the training calibration

    @property
    def settled_error(self) -> float:
        return self.settled_change[1] - self.settled_change[0]

    @property
    def peak_change_error(self) -> float:
        return self.peak_change[1] - self.peak_change[0]

    @property
    def rise_time_error(self) -> float | None:
        return _difference(self.rise_time)

    @property
    def time_to_peak_error(self) -> float | None:
        return _difference(self.time_to_peak)

    @property
    def settling_time_error(self) -> float | None:
        return _difference(self.settling_time)


def _difference(pair: Pair) -> float | None:
    m, s = pair
    if m is None or s is None:
        return None
    if math.isinf(m) or math.isinf(s):
        return 0.0 if m == s else math.inf
    return s - m


@dataclass(frozen=True)
class Compared:
    """A measured and a simulated curve on one time base, NaN where a sample is not
    compared, with the judged span (event to end, :func:`span`) and the recorder's noise
    level: what the metrics are read from."""

    test: str
    output: str
    time: np.ndarray
    measured: np.ndarray
    simulated: np.ndarray
    event: float
    end: float
    noise: float | None


def span(exp, t: np.ndarray) -> tuple[float, float]:
    """(event, end) of the judged span on the time base ``t`` (module docstring)."""
    t0 = exp.pre_step_end if exp.pre_step_end is not None else float(t[0])
    t_end = float(t[-1])
    t_return = exp.fixed.get("src.t_return")
    if t_return is not None and t0 < t_return < t_end:
        t_end = float(t_return)
    return t0, t_end


def metrics_of(curve: Compared, role: str = "training", residual: np.ndarray | None = None) -> ValidationMetrics:
    """The metrics of a measured and a simulated curve: what
    :func:`rapid_cosim.validation.curves.metrics` reads off a fit (its ``residual`` as the
    fit computed it), and what a noise replicate of a
    record's playback is judged on (:mod:`rapid_cosim.fleet.playback`)."""
    name, out, t, measured, simulated = curve.test, curve.output, curve.time, curve.measured, curve.simulated
    t0, t_end, noise = curve.event, curve.end, curve.noise
    r = measured - simulated if residual is None else residual
    ok = np.isfinite(r)
    sigma = noise if noise is not None and np.isfinite(noise) else 0.0
    shapes = [_shape(t, y, ok, t0, t_end) for y in (measured, simulated)]
    change_m = shapes[0].change
    overshoot = (np.isfinite(change_m) and abs(shapes[0].peak) - abs(change_m)
                 > max(OVERSHOOT_SHARE * abs(change_m), OVERSHOOT_IN_NOISE * sigma))
    band = max(SETTLING_SHARE * abs(change_m), SETTLING_IN_NOISE * sigma) if np.isfinite(change_m) else 0.0
    rise, peak_t, settle = [], [], []
    for s in shapes:
        rise.append(s.time_to(RESPONSE_LEVEL))
        peak_t.append(s.peak_time if overshoot else None)
        settle.append(s.settling(band))
    if not np.isfinite(change_m) or abs(change_m) < MIN_CHANGE_IN_NOISE * sigma or change_m == 0:
        rise, peak_t, settle = [None, None], [None, None], [None, None]
    return ValidationMetrics(name, out, float(np.sqrt(np.mean(r[ok] ** 2))), float(np.max(np.abs(r[ok]))),
                             (shapes[0].change, shapes[1].change), (shapes[0].peak, shapes[1].peak),
                             (rise[0], rise[1]), (peak_t[0], peak_t[1]), (settle[0], settle[1]), noise, role)


@dataclass(frozen=True)
class _Shape:
    """One response over the span: times after the event and the smoothed change."""

    time: np.ndarray  # s after the event
    smooth: np.ndarray  # smoothed change from the pre-event level
    change: float  # settled change (mean of the last 10 %, unsmoothed)

    @property
    def _toward(self) -> np.ndarray:
        return self.smooth * (1.0 if self.change >= 0 else -1.0)

    @property
    def peak(self) -> float:
        if self.smooth.size == 0 or not np.isfinite(self.change):
            return float("nan")
        return float(self.smooth[int(np.argmax(self._toward))])

    @property
    def peak_time(self) -> float | None:
        return None if self.smooth.size == 0 else float(self.time[int(np.argmax(self._toward))])

    def time_to(self, share: float) -> float | None:
        if self.smooth.size == 0 or not np.isfinite(self.change) or self.change == 0:
            return None
        reached = np.flatnonzero(self.smooth / self.change >= share)
        return None if reached.size == 0 else float(self.time[reached[0]])

    def settling(self, band: float) -> float | None:
        if self.smooth.size == 0 or not np.isfinite(self.change):
            return None
        outside = np.flatnonzero(np.abs(self.smooth - self.change) > band)
        if outside.size == 0:
            return 0.0
        last = int(outside[-1])
        return math.inf if last + 1 >= self.time.size else float(self.time[last + 1])


def _shape(t, y, ok, t0, t_end) -> _Shape:
    before = ok & (t < t0)
    base = float(np.mean(y[before])) if before.any() else float(y[ok][0])
    settled = ok & (t >= t_end - SETTLED_SHARE * (t_end - t0)) & (t < t_end)
    change = float(np.mean(y[settled])) - base if settled.any() else float("nan")
    after = ok & (t >= t0) & (t < t_end)
    if after.sum() < 3:
        return _Shape(np.empty(0), np.empty(0), change)
    tt, yy = t[after], y[after] - base
    dt = float(np.median(np.diff(tt)))
    return _Shape(tt - t0, _moving_mean(yy, max(1, int(round(SMOOTHING_S / dt)))), change)


def _moving_mean(y: np.ndarray, k: int) -> np.ndarray:
    """Centred mean over ``k`` samples, over fewer at the ends (no padding pulls them)."""
    if k <= 1 or y.size <= k:
        return y.copy()
    c = np.concatenate([[0.0], np.cumsum(y)])
    i = np.arange(y.size)
    lo = np.clip(i - k // 2, 0, y.size)
    hi = np.clip(i - k // 2 + k, 0, y.size)
    return (c[hi] - c[lo]) / (hi - lo)
