"""Per-test error metrics of a calibrated model, as model-validation reports for a unit's
primary frequency response state them.

All are computed on the measured time base inside the fitness window, from the
measured output (converted as configured) and the simulation with its profiled offset:

``rmse``
    root mean square of the residual.
``peak_error``
    the largest absolute residual.
``settled_change`` (measured, simulated) and ``settled_error``
    the change of the output from its pre-event level (mean before the event) to its
    settled level (mean of the last 10 % of the span before the next event: the end of
    the window, or a staged test's return step), and the simulation's error in it.
``response_time`` (measured, simulated) and ``response_time_error``
    the time from the event to the first sample where the output, smoothed by a centred
    moving mean over 1 s, has covered 90 % of its settled change. Undefined (None)
    when the measured change is under five noise levels: the time would be the noise's.

The event is ``[fitness] pre_step_end`` (else the start of the window).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .archives import FitCurves

SETTLED_SHARE = 0.10
RESPONSE_LEVEL = 0.90
SMOOTHING_S = 1.0
MIN_CHANGE_IN_NOISE = 5.0


@dataclass(frozen=True)
class ValidationMetrics:
    experiment: str
    output: str
    rmse: float
    peak_error: float
    settled_change: tuple[float, float]  # measured, simulated
    response_time: tuple[float | None, float | None]  # measured, simulated (s after the event)
    noise: float | None  # the experiment's noise level, for scale

    @property
    def settled_error(self) -> float:
        return self.settled_change[1] - self.settled_change[0]

    @property
    def response_time_error(self) -> float | None:
        m, s = self.response_time
        return None if m is None or s is None else s - m


def metrics(curves: FitCurves) -> ValidationMetrics:
    exp = curves.detail.experiment
    out = curves.output
    t = np.asarray(curves.detail.fit.time, dtype=float)
    r = np.asarray(curves.residual, dtype=float)
    ok = np.isfinite(r)
    measured_all, _ = exp.measured(out)
    idx = np.flatnonzero((exp.data.time >= t[0]) & (exp.data.time <= t[-1]))
    measured = np.where(ok, measured_all[idx], np.nan)
    simulated = np.where(ok, measured - r, np.nan)
    t0 = exp.pre_step_end if exp.pre_step_end is not None else float(t[0])
    t_end = float(t[-1])
    t_return = exp.fixed.get("src.t_return")
    if t_return is not None and t0 < t_return < t_end:
        t_end = float(t_return)
    before = ok & (t < t0)
    settled = ok & (t >= t_end - SETTLED_SHARE * (t_end - t0)) & (t < t_end)
    noise = None if exp.noise_sigma is None else float(exp.noise_sigma.get(out, np.nan))
    changes, times = [], []
    for y in (measured, simulated):
        base = float(np.mean(y[before])) if before.any() else float(y[ok][0])
        change = float(np.mean(y[settled])) - base if settled.any() else float("nan")
        changes.append(change)
        times.append(_response_time(t, y, ok, t0, t_end, base, change))
    if noise is not None and np.isfinite(noise) and abs(changes[0]) < MIN_CHANGE_IN_NOISE * noise:
        times = [None, None]
    return ValidationMetrics(exp.name, out, float(np.sqrt(np.mean(r[ok] ** 2))), float(np.max(np.abs(r[ok]))),
                             (changes[0], changes[1]), (times[0], times[1]), noise)


def _response_time(t, y, ok, t0, t_end, base, change) -> float | None:
    if not np.isfinite(change) or change == 0:
        return None
    after = ok & (t >= t0) & (t < t_end)
    if after.sum() < 3:
        return None
    tt, yy = t[after], y[after]
    dt = float(np.median(np.diff(tt)))
    k = max(1, int(round(SMOOTHING_S / dt)))
    smooth = np.convolve(yy - base, np.ones(k) / k, mode="same") if yy.size > k else yy - base
    reached = np.flatnonzero(smooth / change >= RESPONSE_LEVEL)
    return None if reached.size == 0 else float(tt[reached[0]] - t0)
