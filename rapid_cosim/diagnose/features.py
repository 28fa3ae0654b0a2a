"""Residual analysis: where the base model's residual is systematic rather than noise,
and features of the data that point at a cause.

Whiteness is judged against each test's recorder noise (:mod:`rapid_cosim.noise`): the
residual, whitened by the noise model, should be white (Ljung-Box on 10 lags) and of unit
variance (a chi-square variance test), in every 10 s window. Windows that fail either are
called systematic. (These screen where to look; the verdict's adequacy has its own,
computed null: :mod:`.adequacy`.)

Features are computed on the measurements (and the base fit) per test:

=====================  ===============================================  =================
feature                what it measures                                  points at
=====================  ===============================================  =================
lag_s                  shift maximising the correlation of measured and  delay, measurement
                       simulated increments (positive: data later)        lag
asymmetry              rise speed / fall speed of the response           rate_limit
                       (0-63 % times, step vs return or up vs down)
step_scaling           response per Hz of the smaller step over that of  deadband, backlash
                       the larger one (1 for a linear plant)
ramp_fraction          share of the rise spent at nearly constant slope  rate_limit
return_residue         level after the return step minus the level       backlash
                       before the step, in units of the step response
withdrawal             fall of the response over the second half of the  load_controller
                       step, in units of the step response
pre_step_bias          mean residual before the step, in standard        measurement offset
                       errors of that mean
=====================  ===============================================  =================
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Mapping, Sequence

import numpy as np
from scipy import stats

from ..experiment import Experiment
from .candidates import ExperimentResiduals
from .selection import NoiseFloor

WINDOW_S = 10.0
LAGS = 10
ALPHA = 0.01


@dataclass
class Window:
    start: float
    end: float
    ljung_box_p: float
    variance_ratio: float
    variance_p: float
    systematic: bool


@dataclass
class TestFeatures:
    name: str
    df_hz: float
    has_return: bool
    systematic_share: float  # of the post-step windows
    windows: list[Window]
    lag_s: float
    step_response: float  # measured change during the step (pu)
    per_hz: float  # step_response / |df|
    rise_time_s: float | None  # 63 % time after the step
    fall_time_s: float | None  # 63 % time after the return
    ramp_fraction: float | None
    return_residue: float | None  # in units of the step response
    withdrawal: float | None  # in units of the step response
    pre_step_bias: float  # in standard errors
    notes: list[str] = field(default_factory=list)  # features read differently, or skipped, and why


@dataclass
class Features:
    tests: list[TestFeatures] = field(default_factory=list)
    summary: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return asdict(self)


def _mean_in(t, y, a, b):
    m = (t >= a) & (t < b) & np.isfinite(y)
    return float(np.mean(y[m])) if m.any() else float("nan")


def _windows(t, r, floor: NoiseFloor, start: float) -> list[Window]:
    out = []
    edges = np.arange(start, t[-1] + 1e-9, WINDOW_S)
    for a, b in zip(edges[:-1], edges[1:]):
        m = (t >= a) & (t < b)
        e = floor.whiten(r[m] - np.nanmean(r[m])) if np.isfinite(r[m]).any() else np.zeros(0)
        if e.size < LAGS + 5:
            continue
        e0 = e - e.mean()
        denom = np.sum(e0 ** 2)
        rho = np.array([np.sum(e0[k:] * e0[:-k]) / denom for k in range(1, LAGS + 1)])
        n = e.size
        q = n * (n + 2) * np.sum(rho ** 2 / (n - np.arange(1, LAGS + 1)))
        p_lb = float(stats.chi2.sf(q, LAGS))
        ratio = float(np.mean(e ** 2))
        p_var = float(stats.chi2.sf(ratio * n, n))
        out.append(Window(float(a), float(b), p_lb, ratio, p_var, p_lb < ALPHA or p_var < ALPHA))
    return out


def _lag(t, y, yhat, max_lag_s=3.0) -> float:
    ok = np.isfinite(y) & np.isfinite(yhat)
    if ok.sum() < 20:
        return 0.0
    dt = float(np.median(np.diff(t)))
    grid = np.arange(t[0], t[-1], dt)
    dy = np.diff(np.interp(grid, t[ok], y[ok]))
    dm = np.diff(np.interp(grid, t[ok], yhat[ok]))
    k_max = int(round(max_lag_s / dt))
    best, best_k = -np.inf, 0
    for k in range(-k_max, k_max + 1):
        a, b = (dy[k:], dm[:dy.size - k]) if k >= 0 else (dy[:k], dm[-k:])
        c = float(np.dot(a - a.mean(), b - b.mean()))
        if c > best:
            best, best_k = c, k
    return best_k * dt


def _time_to(t, y, t0, t1, y0, y1, share=0.63) -> float | None:
    """Time after t0 at which y first covers ``share`` of the way from y0 to y1."""
    m = (t >= t0) & (t < t1) & np.isfinite(y)
    if not m.any() or abs(y1 - y0) < 1e-12:
        return None
    progress = (y[m] - y0) / (y1 - y0)
    hit = np.flatnonzero(progress >= share)
    return float(t[m][hit[0]] - t0) if hit.size else None


def _ramp_fraction(t, y, t0, t1, y0, y1, window_s: float = 2.0) -> float | None:
    """Share of the 10-90 % rise where the slope (least squares over ``window_s``) is
    within 25 % of its 90th percentile: a ramp holds its slope, a lag's slope decays."""
    m = (t >= t0) & (t < t1) & np.isfinite(y)
    if m.sum() < 20 or abs(y1 - y0) < 1e-12:
        return None
    tt, yy = t[m], (y[m] - y0) / (y1 - y0)
    k = max(int(round(window_s / np.median(np.diff(tt)))), 3)
    if tt.size <= k:
        return None

    def window_sum(v):
        c = np.concatenate([[0.0], np.cumsum(v)])
        return c[k:] - c[:-k]

    st, sy, stt, sty = window_sum(tt), window_sum(yy), window_sum(tt * tt), window_sum(tt * yy)
    slope = (k * sty - st * sy) / (k * stt - st * st)
    level = sy / k
    inside = (level > 0.1) & (level < 0.9)
    if inside.sum() < 5:
        return None
    peak = np.quantile(slope[inside], 0.9)
    return float(np.mean(slope[inside] > 0.75 * peak)) if peak > 0 else None


def test_features(exp: Experiment, residual: np.ndarray, time: np.ndarray, floor: NoiseFloor) -> TestFeatures:
    (out,) = [o for o in exp.outputs if exp.weights[o] > 0]
    data = exp.windowed_data()
    inside = np.flatnonzero((exp.data.time >= data.time[0]) & (exp.data.time <= data.time[-1]))
    t, y = data.time, exp.measured(out)[0][inside]  # as compared: converted to the model's units
    notes: list[str] = []
    if exp.inputs:
        t_step, t_ret, df = _recorded_move(exp, notes)
    else:
        t_step = float(exp.fixed.get("src.t_step", 10.0))
        t_ret = float(exp.fixed.get("src.t_return", np.inf))
        df = float(exp.fixed.get("src.df", np.nan))
    has_return = t_ret < t[-1] - 10.0
    step_end = min(t_ret, t[-1])
    y0 = _mean_in(t, y, t[0], t_step)
    y1 = _mean_in(t, y, step_end - 0.25 * (step_end - t_step), step_end)
    yhat = y - residual  # the base model's (offset-corrected) prediction on the same samples
    response = y1 - y0
    half = _mean_in(t, y, t_step + 0.4 * (step_end - t_step), t_step + 0.6 * (step_end - t_step))
    withdrawal = (half - y1) / response if abs(response) > 0 else None
    rise = _time_to(t, y, t_step, step_end, y0, y1)
    fall, residue = None, None
    if has_return:
        y2 = _mean_in(t, y, t[-1] - 0.3 * (t[-1] - t_ret), t[-1])
        fall = _time_to(t, y, t_ret, t[-1], y1, y2)
        residue = (y2 - y0) / response if abs(response) > 0 else None
    pre = np.isfinite(residual) & (time < t_step)
    bias = float(np.mean(residual[pre]) / floor.mean_se(int(pre.sum()))) if pre.any() else 0.0
    windows = _windows(time, residual, floor, t_step)
    systematic = float(np.mean([w.systematic for w in windows])) if windows else 0.0
    return TestFeatures(
        name=exp.name, df_hz=df, has_return=has_return, systematic_share=systematic, windows=windows,
        lag_s=_lag(time, y, yhat), step_response=float(response),
        per_hz=float(abs(response) / abs(df)) if df else float("nan"), rise_time_s=rise, fall_time_s=fall,
        ramp_fraction=_ramp_fraction(t, y, t_step, step_end, y0, y1), return_residue=residue,
        withdrawal=withdrawal, pre_step_bias=bias, notes=notes)


def _recorded_move(exp: Experiment, notes: list[str]) -> tuple[float, float, float]:
    """(event time, no return, step size in Hz) of an input-driven experiment, read from
    its first input's own movement: the event at ``pre_step_end``, the size the change
    from the pre-event level to the settled level of the last quarter."""
    spec = exp.inputs[0]
    table = exp.input_table
    t_event = exp.pre_step_end if exp.pre_step_end is not None else float(table.time[0])
    u = table.values[:, 0]
    pre = table.time < t_event
    late = table.time >= table.time[0] + 0.75 * (table.time[-1] - table.time[0])
    change = float(np.mean(u[late]) - np.mean(u[pre])) if pre.any() and late.any() else float("nan")
    c = spec.conversion
    if c.convert == "deviation_pu" and c.nominal:
        hz = change * c.nominal * c.sign / c.scale
    elif c.unit in ("Hz", "mHz") or c.convert == "deviation":
        hz = change * c.sign / c.scale
    else:
        hz = float("nan")
        notes.append(f"input {spec.name} is not a frequency in Hz: step scaling and up/down moves are skipped")
    notes.append(f"recorded input {spec.name}: the event is taken at {t_event:g} s and its size is the "
                 f"input's settled change ({hz * 1000:+.0f} mHz); no return step")
    return float(t_event), float("inf"), hz


def residual_features(experiments: Sequence[Experiment], tests: Mapping[str, ExperimentResiduals],
                      noise: Mapping[str, NoiseFloor]) -> Features:
    """Features of every test, from the data and the base model's residuals (``tests``,
    held-out ones predicted)."""
    per_test = [test_features(e, tests[e.name].residual, tests[e.name].time, noise[e.name]) for e in experiments]
    return Features(per_test, _summary(per_test))


def _summary(tests: list[TestFeatures]) -> dict:
    """Campaign-level readings of the features, each with the effect it points at."""
    out: dict = {}
    sizes = sorted({round(abs(t.df_hz), 4) for t in tests if np.isfinite(t.df_hz)})
    if len(sizes) >= 2:
        small = [t.per_hz for t in tests if round(abs(t.df_hz), 4) == sizes[0]]
        large = [t.per_hz for t in tests if round(abs(t.df_hz), 4) == sizes[-1]]
        out["step_scaling"] = {"value": float(np.mean(small) / np.mean(large)), "points_at": ["deadband", "backlash"],
                               "reading": "1 if the response scales with the step size; below 1 if small steps "
                                          "respond less than in proportion"}
    else:
        out["step_scaling"] = {"value": None, "points_at": ["deadband"],
                               "reading": "one step size only: a deadband cannot be told from a larger droop"}
    rises = [t.rise_time_s for t in tests if t.rise_time_s]
    falls = [t.fall_time_s for t in tests if t.fall_time_s]
    ups = [t.rise_time_s for t in tests if t.rise_time_s and t.df_hz < 0] + \
          [t.fall_time_s for t in tests if t.fall_time_s and t.df_hz > 0]
    downs = [t.rise_time_s for t in tests if t.rise_time_s and t.df_hz > 0] + \
            [t.fall_time_s for t in tests if t.fall_time_s and t.df_hz < 0]
    if ups and downs:
        out["asymmetry"] = {"value": float(np.mean(ups) / np.mean(downs)), "points_at": ["rate_limit"],
                            "reading": "63 % time of power increases over that of decreases (1: symmetric)"}
    out["rise_over_fall"] = float(np.mean(rises) / np.mean(falls)) if rises and falls else None
    ramps = [t.ramp_fraction for t in tests if t.ramp_fraction is not None]
    out["ramp_fraction"] = {"value": float(np.mean(ramps)) if ramps else None, "points_at": ["rate_limit"],
                            "reading": "share of the rise at nearly constant slope: about 0.3 for a lag, more for "
                                       "a ramp (a turbine's own lags smooth a valve's ramp, so a low value does "
                                       "not exclude a rate limit)"}
    residues = [t.return_residue for t in tests if t.return_residue is not None]
    out["return_residue"] = {"value": float(np.mean(np.abs(residues))) if residues else None,
                             "points_at": ["backlash"],
                             "reading": "part of the step response still there after the return (0: it all came back)"}
    withdrawals = [t.withdrawal for t in tests if t.withdrawal is not None]
    out["withdrawal"] = {"value": float(np.mean(withdrawals)) if withdrawals else None, "points_at": ["load_controller"],
                         "reading": "share of the response given back during the second half of the step"}
    out["lag_s"] = {"value": float(np.median([t.lag_s for t in tests])), "points_at": ["delay", "measurement_lag"],
                    "reading": "shift of the measured response against the base model's (positive: data later)"}
    out["pre_step_bias"] = {"value": float(np.max(np.abs([t.pre_step_bias for t in tests]))),
                            "points_at": ["measurement offset"],
                            "reading": "largest mean residual before the step, in standard errors; the offset "
                                       "is profiled over the whole record, so a misfit after the step shows "
                                       "here too"}
    out["systematic_share"] = {t.name: t.systematic_share for t in tests}
    return out
