"""Does a model fit to the noise? The adequacy check every verdict carries, and where
the misfit lies when it does not.

Per test, the model's residual (held-out tests predicted) is whitened by the recorder's
noise model, the offset profiled out, and two statistics are read:

``variance_ratio``
    the mean squared whitened residual: near 1 for a model that leaves only the noise;
``ljung_box_q``
    the Ljung-Box statistic (10 lags) of the whitened residual: large when it is still
    correlated, i.e. structured.

Neither is compared with a fixed gate. Their null distribution, what a correct model
would leave on *this* test, is computed (:mod:`.null`: a parametric bootstrap over the
noise model and its uncertainty, the test's own samples and gaps, the offset, and the
fitted parameters' share). Each test gets the bootstrap p-value of each statistic and of
the smaller of the two (the min-p combination); Holm's step-down adjustment over the
tests keeps the family-wise false alarm of the campaign at :data:`ALPHA`. A campaign is
adequate when no test is rejected; its p-value is the smallest adjusted one.

Timing jitter: a time stamp off by ``d`` seconds misplaces a sample by ``d`` times the
slope of the response. :func:`jitter_share` bounds the variance that adds, if the stamps
were that wrong, as a share of the noise variance; it is reported with the verdict.

:func:`misfit_locations` splits the remaining residual by phase (before the step,
after power-raising and power-lowering moves, in steady state, after the return) and
reads its drift and its scaling with the step size, so that ``unexplained`` says where
to look.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Mapping, Sequence

import numpy as np

from ..experiment import Experiment
from .candidates import ExperimentResiduals
from .null import LAGS, NoiseReplicates, combined_p, holm, ljung_box_q, timing_jitter, upper_p
from .selection import NoiseFloor, whitened

ALPHA = 0.01  # family-wise false-alarm rate of a campaign's adequacy
TRANSIENT_S = 20.0  # after a move, the span read as its transient
PHASE_FLAG = 1.5  # a phase whose RMS residual exceeds this many noise levels is named


@dataclass(frozen=True)
class TestAdequacy:
    test: str
    variance_ratio: float
    ljung_box_q: float
    p_variance: float
    p_whiteness: float
    p: float  # of the two combined (min-p)
    p_holm: float  # adjusted over the campaign's tests
    rmse_over_noise: float
    n: int
    adequate: bool

    def to_json(self) -> dict:
        """As a report holds it, under its test's name (the name is the key, not a field)."""
        return {k: v for k, v in asdict(self).items() if k != "test"}


@dataclass(frozen=True)
class Adequacy:
    adequate: bool
    pooled_variance_ratio: float
    p: float  # the campaign's: the smallest Holm-adjusted p-value
    alpha: float
    replicates: int
    tests: tuple[TestAdequacy, ...]

    @property
    def failing(self) -> list[str]:
        return [t.test for t in self.tests if not t.adequate]

    def to_json(self) -> dict:
        return {"adequate": self.adequate, "pooled_variance_ratio": self.pooled_variance_ratio, "p": self.p,
                "alpha": self.alpha, "replicates": self.replicates,
                "tests": {t.test: t.to_json() for t in self.tests}}


def adequacy(tests: Mapping[str, ExperimentResiduals], noise: Mapping[str, NoiseFloor], null: NoiseReplicates,
             jacobians: Mapping[str, np.ndarray] | None, training: Sequence[str], alpha: float = ALPHA) -> Adequacy:
    """The adequacy of the model whose residuals are ``tests``, with the Jacobians of its
    whitened residuals at the optimum (per test; None: nothing fitted) and the names of
    the tests it was fitted on."""
    replicates = null.statistics(jacobians, [t for t in training if t in tests], LAGS)
    rows, num, den, pvals = [], 0.0, 0, {}
    observed = {}
    for name, fit in tests.items():
        e = whitened(fit, noise[name])
        v, q = float(np.mean(e ** 2)), float(ljung_box_q(e, LAGS)[0])
        pv, pq, pm = combined_p(v, q, *replicates[name])
        observed[name] = (v, q, pv, pq, e.size, fit)
        pvals[name] = pm
        num += float(np.sum(e ** 2))
        den += e.size
    adjusted = holm(pvals)
    for name, (v, q, pv, pq, n, fit) in observed.items():
        r = fit.residual[np.isfinite(fit.residual)]
        rows.append(TestAdequacy(name, v, q, pv, pq, pvals[name], adjusted[name],
                                 float(np.sqrt(np.mean(r ** 2)) / noise[name].sigma), n, adjusted[name] >= alpha))
    p_campaign = min(adjusted.values()) if adjusted else 1.0
    return Adequacy(p_campaign >= alpha, num / den if den else float("nan"), p_campaign, alpha, null.replicates,
                    tuple(rows))


@dataclass(frozen=True)
class ScoreTest:
    """Are the parameters where the recordings put them? The Lagrange-multiplier (score)
    test at a given point: ``S = g' A^-1 g`` with ``g = J' e`` and ``A = J' J`` summed
    over the tests (``e`` the whitened, offset-profiled residual, ``J`` its Jacobian in
    the parameters), i.e. what one Gauss-Newton step from the point would take off the
    criterion. Against a parameter moved from its true value it is far more sensitive
    than the residual's variance, whose excess is spread over every sample; its null is
    read off the same noise replicates as the variance's (chi-square with as many
    degrees of freedom as parameters, were the noise model exact)."""

    statistic: float
    p: float
    step: tuple[float, ...]  # the Gauss-Newton step, in the parameters' own units
    gains: tuple[float, ...]  # what refitting each parameter alone would take off (g_j^2 / A_jj)
    alone: tuple[float, ...]  # each parameter's own step, were it refitted alone (-g_j / A_jj)


def score_test(residuals: Mapping[str, np.ndarray], jacobians: Mapping[str, np.ndarray],
               null: NoiseReplicates) -> ScoreTest:
    """The score test of the point whose whitened residuals (valid samples, per test) and
    their Jacobians (samples x parameters) are given (:class:`ScoreTest`)."""
    names = list(jacobians)
    A = sum(jacobians[n].T @ jacobians[n] for n in names)
    g = sum(jacobians[n].T @ residuals[n] for n in names)
    diag = np.where(np.diag(A) > 0, np.diag(A), np.inf)
    d = 1.0 / np.sqrt(diag)  # columns to unit norm first: parameters in their own units differ by decades
    A_inv = d[:, None] * np.linalg.pinv(d[:, None] * A * d[None, :]) * d[None, :]
    g_null = sum(null.e[n].astype(float) @ jacobians[n] for n in names)
    s_null = np.einsum("ri,ij,rj->r", g_null, A_inv, g_null)
    s = float(g @ A_inv @ g)
    return ScoreTest(s, upper_p(s, s_null), tuple(float(v) for v in -(A_inv @ g)),
                     tuple(float(v) for v in g * g / diag), tuple(float(v) for v in -g / diag))


def jitter_share(tests: Mapping[str, ExperimentResiduals], noise: Mapping[str, NoiseFloor]) -> dict:
    """Per test, the time stamps' jitter (ms) and the variance it would add at the
    model's slopes, as a share of the noise variance (mean over the record, and over
    its steepest second)."""
    out = {}
    for name, fit in tests.items():
        if fit.simulated is None:
            continue
        t = np.asarray(fit.time, dtype=float)
        jitter = timing_jitter(t)
        slope = np.gradient(fit.simulated, t)
        added = jitter ** 2 * slope ** 2 / noise[name].sigma ** 2
        dt = float(np.median(np.diff(t)))
        width = max(int(round(1.0 / dt)), 1)
        steepest = float(np.max(np.convolve(added, np.ones(width) / width, mode="valid"))) if added.size >= width \
            else float(np.max(added))
        out[name] = {"jitter_ms": 1e3 * jitter, "variance_share": float(np.mean(added)),
                     "steepest_second_share": steepest}
    return out


def misfit_locations(experiments: Sequence[Experiment], tests: Mapping[str, ExperimentResiduals],
                     noise: Mapping[str, NoiseFloor]) -> dict:
    """RMS residual (in noise levels) per phase over the campaign, the phases above
    :data:`PHASE_FLAG`, the drift (change of the residual's level per minute, in noise
    levels) and the correlation of each test's misfit with its step size."""
    sums: dict[str, list[float]] = {}
    per_test, sizes, drifts = {}, [], []
    for exp in experiments:
        fit = tests.get(exp.name)
        if fit is None:
            continue
        t, r = fit.time, fit.residual / noise[exp.name].sigma
        ok = np.isfinite(r)
        for phase, mask in _phases(exp, t).items():
            m = mask & ok
            if m.any():
                sums.setdefault(phase, []).extend((r[m] ** 2).tolist())
        rms = float(np.sqrt(np.mean(r[ok] ** 2)))
        per_test[exp.name] = rms
        df = exp.fixed.get("src.df")
        if df is not None:
            sizes.append((abs(float(df)), rms))
        if ok.sum() > 10:
            drifts.append(float(np.polyfit(t[ok], r[ok], 1)[0]) * 60.0)
    phases = {k: float(np.sqrt(np.mean(v))) for k, v in sums.items()}
    scaling = None
    if len({s for s, _ in sizes}) >= 2:
        a = np.array(sizes)
        scaling = float(np.corrcoef(a[:, 0], a[:, 1])[0, 1])
    drift = float(np.median(drifts)) if drifts else 0.0
    return {"phases": phases, "flagged": [k for k, v in phases.items() if v > PHASE_FLAG],
            "per_test_rms": per_test, "drift_per_min": drift, "step_size_correlation": scaling,
            "summary": _summary(phases, per_test, drift, scaling)}


def _phases(exp: Experiment, t: np.ndarray) -> dict[str, np.ndarray]:
    if exp.inputs:  # a recorded event: before it, its transient, and the rest
        t0 = exp.pre_step_end if exp.pre_step_end is not None else float(t[0])
        return {"before the event": t < t0, "event transient": (t >= t0) & (t < t0 + TRANSIENT_S),
                "steady state": t >= t0 + TRANSIENT_S}
    t_step = float(exp.fixed.get("src.t_step", 10.0))
    t_ret = float(exp.fixed.get("src.t_return", np.inf))
    df = float(exp.fixed.get("src.df", 0.0))
    up, down = ("after power-raising moves", "after power-lowering moves")
    first, back = (up, down) if df < 0 else (down, up)  # a frequency drop raises power
    out = {"before the step": t < t_step,
           first: (t >= t_step) & (t < min(t_step + TRANSIENT_S, t_ret)),
           "steady state": (t >= t_step + TRANSIENT_S) & (t < t_ret)}
    if np.isfinite(t_ret):
        out[back] = (t >= t_ret) & (t < t_ret + TRANSIENT_S)
        out["after the return, settled"] = t >= t_ret + TRANSIENT_S
    return out


def _summary(phases, per_test, drift, scaling) -> str:
    worst = sorted(phases.items(), key=lambda kv: -kv[1])
    parts = [f"largest in {', '.join(f'{k} ({v:.1f}x noise)' for k, v in worst[:2])}"] if worst else []
    tests = sorted(per_test.items(), key=lambda kv: -kv[1])
    if tests:
        parts.append(f"worst test {tests[0][0]} ({tests[0][1]:.1f}x noise RMS)")
    if abs(drift) > 0.5:
        parts.append(f"drifting {drift:+.1f} noise levels per minute")
    if scaling is not None and abs(scaling) > 0.8:
        parts.append("growing with the step size" if scaling > 0 else "shrinking with the step size")
    return "; ".join(parts)
