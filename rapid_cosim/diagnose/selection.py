"""Model selection: an information criterion on the residuals, corrected for coloured
noise, and the rules that turn a ranking into a verdict.

Criterion. For each test the residual (offset profiled) is prewhitened with the lag-1
autocorrelation ``phi`` of that test's pre-step noise, ``a_t = r_t - phi r_{t-1}``. If
the model is right, ``a`` is white; its variance ``s2`` is then the innovation variance
and the Gaussian AR(1) log-likelihood, concentrated over ``s2``, gives

    BIC = sum_tests n_i log(s2_i) + k log(N)

with ``k`` the estimated parameters (the shared ones plus one offset per test) and ``N``
the number of prewhitened samples. Treating correlated noise as white would count every
sample as new evidence and make any extra parameter look significant; prewhitening with
the noise's own ``phi`` does not, while a systematic misfit (slow, unlike the noise)
still shows.

Verdict (``threshold`` in BIC units, 10 = "very strong" on Kass and Raftery's scale):
- an effect is *named* when it beats ``none`` and every other candidate by at least the
  threshold, and, if held-out tests are given, predicts them better than ``none``;
- ``none`` is returned when nothing beats it, and no effect held at a material size
  fits about as well (which would mean the data cannot exclude that effect);
- otherwise the answer is *ambiguous*, with the candidates that could not be told apart
  and the staged test that would separate them best.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..data import noise_level
from ..experiment import Experiment
from .candidates import CandidateFit, ExperimentResiduals

THRESHOLD = 10.0


@dataclass(frozen=True)
class NoiseFloor:
    """The measurement noise of one test, from its pre-step samples."""

    sigma: float  # standard deviation of the noise
    phi: float  # lag-1 autocorrelation


def _pre_step(exp: Experiment) -> tuple[float, float, int, float]:
    """(sigma, phi, samples, median sample interval) of one test's pre-step noise."""
    (output,) = [o for o in exp.outputs if exp.weights[o] > 0]
    end = exp.pre_step_end if exp.pre_step_end is not None else float(exp.fixed.get("src.t_step", 10.0))
    est = noise_level(exp.data, exp.outputs[output], end)
    conversion = exp.conversions.get(output)  # the level of the compared values (e.g. MW -> pu)
    gain = conversion.gain if conversion is not None else 1.0
    return float(est.sigma * gain), float(np.clip(est.phi, 0.0, 0.95)), est.n, float(np.median(np.diff(exp.data.time)))


def pooled_noise(experiments: Sequence[Experiment]) -> dict[str, NoiseFloor]:
    """Noise floors pooled over the tests recorded at the same rate.

    One transducer and one recorder measured every test of a campaign; a pre-step window
    holds 50 to 250 samples, so a single test's noise level is uncertain by 5 to 10 %,
    enough to make a perfect model look as if it missed something. Tests with the same
    sampling interval (within 10 %) share one estimate, weighted by their sample counts.
    """
    stats_ = {e.name: _pre_step(e) for e in experiments}
    groups: list[list[str]] = []
    for name, (_, _, _, dt) in stats_.items():
        for g in groups:
            if abs(stats_[g[0]][3] - dt) <= 0.1 * dt:
                g.append(name)
                break
        else:
            groups.append([name])
    out = {}
    for g in groups:
        n = np.array([stats_[k][2] for k in g], dtype=float)
        var = np.sum(n * np.array([stats_[k][0] ** 2 for k in g])) / n.sum()
        phi = float(np.sum(n * np.array([stats_[k][1] for k in g])) / n.sum())
        for k in g:
            out[k] = NoiseFloor(float(np.sqrt(var)), phi)
    return out


def prewhitened(residual: np.ndarray, phi: float) -> np.ndarray:
    """Innovations of consecutive valid residual pairs (a gap breaks the chain)."""
    r = np.asarray(residual, dtype=float)
    ok = np.isfinite(r[1:]) & np.isfinite(r[:-1])
    return (r[1:] - phi * r[:-1])[ok]


def score(tests: Mapping[str, ExperimentResiduals], noise: Mapping[str, NoiseFloor]) -> tuple[float, int]:
    """(sum n_i log s2_i, N): the data term of the criterion and its sample count."""
    total, n_total = 0.0, 0
    for name, fit in tests.items():
        a = prewhitened(fit.residual, noise[name].phi)
        total += a.size * math.log(max(float(np.mean(a ** 2)), 1e-300))
        n_total += a.size
    return total, n_total


def bic(fit: CandidateFit, noise: Mapping[str, NoiseFloor]) -> float:
    data_term, n = score(fit.tests, noise)
    k = fit.n_estimated + len(fit.tests)  # + one profiled offset per test
    return data_term + k * math.log(n)


def gap(fit: ExperimentResiduals, floor: NoiseFloor) -> dict[str, float]:
    """RMSE of the residual, its ratio to the noise level, and the gap above the floor."""
    r = fit.residual[np.isfinite(fit.residual)]
    rmse = float(np.sqrt(np.mean(r ** 2)))
    return {"rmse": rmse, "rmse_over_noise": rmse / floor.sigma,
            "gap": float(np.sqrt(max(rmse ** 2 - floor.sigma ** 2, 0.0))), "rssd": fit.rssd}


@dataclass(frozen=True)
class Ranked:
    label: str
    effects: tuple[str, ...]
    bic: float
    delta: float  # to the best
    fitness: float
    parameters: dict[str, float]
    archive: str


@dataclass
class Verdict:
    effect: str  # a catalogue name, "none" or "ambiguous"
    effects: list[str] = field(default_factory=list)  # named effects, greedy order
    candidates: list[str] = field(default_factory=list)  # when ambiguous: which could not be told apart
    reason: str = ""
    held_out: dict | None = None


def rank(fits: Sequence[CandidateFit], noise: Mapping[str, NoiseFloor]) -> list[Ranked]:
    scored = sorted(((bic(f, noise), f) for f in fits), key=lambda t: t[0])
    best = scored[0][0]
    return [Ranked(f.spec.label, f.spec.effects, b, b - best, f.fitness, f.parameters, str(f.archive))
            for b, f in scored]


def _margin(ranking: Sequence[Ranked], candidate: Ranked) -> float:
    """How much better than ``none`` the candidate is (positive: better)."""
    none = next(r for r in ranking if r.label == "none")
    return none.bic - candidate.bic


def decisive(ranking: Sequence[Ranked], threshold: float = THRESHOLD) -> bool:
    """Whether the best candidate is an effect that beats ``none`` by the threshold."""
    best = ranking[0]
    return best.label != "none" and _margin(ranking, best) >= threshold


def decide(ranking: Sequence[Ranked], *, threshold: float = THRESHOLD,
           not_excluded: Sequence[str] = ()) -> Verdict:
    """The verdict from a ranking of single-effect candidates and ``none``.

    ``not_excluded``: effects that, held at a material size, fit within the threshold of
    ``none`` (consulted when no effect beats ``none`` decisively).
    """
    best = ranking[0]
    if not decisive(ranking, threshold):
        closest = best if best.label != "none" else ranking[1]
        support = (f"no effect improves the criterion decisively (closest: {closest.label}, "
                   f"{_margin(ranking, closest):+.1f} against the base model)")
        if not_excluded:
            return Verdict("ambiguous", candidates=["none", *not_excluded],
                           reason=support + "; but the data cannot exclude " + ", ".join(not_excluded)
                                  + " at a material size: it fits as well as the base model with other parameters")
        return Verdict("none", reason=support)
    margin_none = _margin(ranking, best)
    rivals = [r.label for r in ranking[1:] if r.label != "none" and r.delta < threshold]
    if rivals:
        return Verdict("ambiguous", candidates=[best.label, *rivals],
                       reason=f"{best.label} and {', '.join(rivals)} are within {threshold:g} of each other")
    second = ranking[1]
    return Verdict(best.label, effects=[best.label],
                   reason=f"{best.label} beats none by {margin_none:.1f} and the next candidate "
                          f"({second.label}) by {second.delta:.1f}")
