"""How often the adequacy test calls a correct model inadequate, and how often the reported
intervals hold the truth: the calibration study of issue 32.

The true model (the plant's own structure, nothing hidden) is fitted on many draws of the
recorder's noise, exactly as a diagnosis fits its base model (:class:`.context.Context`:
the noise model from the quiet stretches, the whitened multistart fit, the computed null).
Per draw: each test's adequacy p-value (the min-p combination of the variance ratio and
the Ljung-Box statistic, before Holm: uniform on [0, 1] if the null is right), the
campaign's family-wise decision at :data:`~.adequacy.ALPHA` (Holm over its tests), the
pooled variance ratio, and whether each parameter's 90 % interval (as a diagnosis reports
it, :mod:`.intervals`; for a pair the tests fit either way round, either optimum's) holds
the value the plant was made with.

:func:`summary` reads a study: the p-values' distribution (deciles, the share below 1, 5
and 10 %, Kolmogorov-Smirnov against the uniform), the family-wise false-alarm rate with
its 95 % (Clopper-Pearson) interval, and the coverage per parameter.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from scipy import stats

from ..compiler.source import ModelSource
from .adequacy import ALPHA
from .candidates import CandidateSpec
from .context import Context, DiagnoseOptions
from .intervals import LEVEL, exchanged, intervals


@dataclass
class TruthFit:
    """The true model on one draw (module docstring)."""

    label: str
    p: dict[str, float]
    p_variance: dict[str, float]
    p_whiteness: dict[str, float]
    p_campaign: float
    alarm: bool
    variance_ratio: float
    parameters: dict[str, float]
    intervals: dict[str, list[float]]
    covered: dict[str, bool] = field(default_factory=dict)
    exchanged: dict[str, list[float]] = field(default_factory=dict)
    seconds: float = 0.0


def fit_truth(label: str, training, heldout, truth: Mapping[str, float], workdir: str | Path,
              options: DiagnoseOptions, source: ModelSource) -> TruthFit:
    """The base model of ``training`` (its config's own bench: the truth, where nothing is
    hidden), judged as a diagnosis judges it; ``truth`` the plant's values of the
    estimated parameters."""
    t0 = time.perf_counter()
    ctx = Context(training, heldout, workdir, options, source, lambda *_: None)
    base = ctx.fit(CandidateSpec())
    a = ctx.adequacy(base)
    bands = intervals(base, LEVEL)
    other = exchanged(base, bands, ctx.noise)  # the optimum with an exchanged pair swapped
    covered = {k: bool(lo <= truth[k] <= hi or (k in other and other[k][0] <= truth[k] <= other[k][1]))
               for k, (lo, hi) in bands.items() if k in truth}
    return TruthFit(label, {t.test: t.p for t in a.tests}, {t.test: t.p_variance for t in a.tests},
                    {t.test: t.p_whiteness for t in a.tests}, a.p, not a.adequate, a.pooled_variance_ratio,
                    dict(base.parameters), bands, covered, other, time.perf_counter() - t0)


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    a = (1 - level) / 2
    lo = stats.beta.ppf(a, k, n - k + 1) if k > 0 else 0.0
    hi = stats.beta.ppf(1 - a, k + 1, n - k) if k < n else 1.0
    return float(lo), float(hi)


def summary(fits: Sequence[TruthFit], alpha: float = ALPHA) -> dict:
    """The study's figures (module docstring)."""
    p = np.array([v for f in fits for v in f.p.values()])
    alarms = sum(f.alarm for f in fits)
    names = sorted({k for f in fits for k in f.covered})
    coverage = {}
    for name in names:
        hits = [f.covered[name] for f in fits if name in f.covered]
        coverage[name] = {"covered": int(sum(hits)), "draws": len(hits), "share": float(np.mean(hits)),
                          "interval": clopper_pearson(int(sum(hits)), len(hits))}
    ks = stats.kstest(p, "uniform") if p.size else None
    return {"draws": len(fits), "tests": int(p.size),
            "p_deciles": np.histogram(p, bins=np.linspace(0, 1, 11))[0].tolist(),
            "p_below": {str(x): float(np.mean(p < x)) for x in (0.01, 0.05, 0.1)} if p.size else {},
            "ks": {"statistic": float(ks.statistic), "p": float(ks.pvalue)} if ks else None,
            "alpha": alpha, "alarms": alarms, "false_alarm_rate": alarms / len(fits) if fits else float("nan"),
            "false_alarm_interval": clopper_pearson(alarms, len(fits)) if fits else (float("nan"),) * 2,
            "variance_ratio": {"median": float(np.median([f.variance_ratio for f in fits])),
                               "max": float(np.max([f.variance_ratio for f in fits]))} if fits else {},
            "coverage": coverage, "level": LEVEL,
            "alarmed": [{"label": f.label, "p_campaign": f.p_campaign,
                         "tests": {t: [f.p[t], f.p_variance[t], f.p_whiteness[t]] for t in f.p}}
                        for f in fits if f.alarm]}


def summary_text(name: str, s: Mapping) -> str:
    """A few lines of :func:`summary`, as the benchmarks print them."""
    lo, hi = s["false_alarm_interval"]
    lines = [f"{name}: the true model on {s['draws']} noise draws ({s['tests']} tests)",
             f"  adequacy p-values (per test, before Holm): deciles {s['p_deciles']}; below 0.01 "
             f"{s['p_below'].get('0.01', float('nan')):.3f}, 0.05 {s['p_below'].get('0.05', float('nan')):.3f}, "
             f"0.1 {s['p_below'].get('0.1', float('nan')):.3f}; Kolmogorov-Smirnov against the uniform "
             f"p {s['ks']['p']:.2g}" if s["ks"] else "  no p-values",
             f"  family-wise false alarms at {s['alpha']:g}: {s['alarms']}/{s['draws']} = "
             f"{s['false_alarm_rate']:.3f} (95 % interval {lo:.3f}-{hi:.3f}); variance ratio median "
             f"{s['variance_ratio'].get('median', float('nan')):.3f}, max {s['variance_ratio'].get('max', float('nan')):.3f}"]
    if s["coverage"]:
        lines.append(f"  coverage of the {int(100 * s['level'])} % intervals: " + ", ".join(
            f"{k} {v['covered']}/{v['draws']} = {v['share']:.2f}" for k, v in s["coverage"].items()))
    for a in s["alarmed"]:
        worst = min(a["tests"].items(), key=lambda kv: kv[1][0])
        lines.append(f"  alarm: {a['label']} (campaign p {a['p_campaign']:.2g}; {worst[0]}: p {worst[1][0]:.2g}, "
                     f"variance {worst[1][1]:.2g}, whiteness {worst[1][2]:.2g})")
    return "\n".join(lines)


def to_json(fits: Sequence[TruthFit]) -> list[dict]:
    return [asdict(f) for f in fits]
