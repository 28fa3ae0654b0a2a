"""Model selection: an information criterion on the residuals, corrected for coloured
noise, and the rules that turn a ranking into a verdict.

Criterion. Each test's residual (offset profiled) is whitened with the recorder's noise
model (:mod:`rapid_cosim.noise`: white plus slow components, fitted to every quiet
stretch of the recorder's tests): the standardised Kalman innovations ``a``. If the
model is right, ``a`` is white; concentrating each test's variance ``s2_i = mean(a^2)``
out of the Gaussian log-likelihood gives

    BIC = sum_tests n_i log(s2_i) + k log(N)

with ``k`` the estimated parameters (the shared ones plus one offset per test) and ``N``
the number of whitened samples. Treating correlated noise as white would count every
sample as new evidence and make any extra parameter look significant; whitening with
the noise's own model does not, while a systematic misfit (slow, unlike the noise) still
shows. The concentrated variance keeps the ranking right when the model's level is off.

Verdict (``threshold`` in BIC units, 10 = "very strong" on Kass and Raftery's scale):
- an effect is *named* when it beats ``none`` and every other candidate by at least the
  threshold, and, if held-out tests are given, predicts them better than ``none``;
- ``none`` is returned when no effect beats it by the threshold; an effect that, held at
  a material size, fits about as well is a caveat of that verdict (``not_excluded``, with
  the staged test that would tell), not a verdict of its own;
- when effects tie within the threshold on the training tests and held-out tests are
  given, their predictions of those tests are added as further evidence: the held-out
  data term is a log-likelihood ratio on data no fit has seen, in the criterion's units,
  so training difference plus held-out difference is compared with the same threshold;
- *ambiguous* is kept for two or more effects that each beat ``none`` by the threshold
  and lie within it of each other: the candidates that could not be told apart and the
  staged test that would separate them best.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from ..experiment import Experiment
from ..noise import NoiseFit, campaign_noise
from .candidates import CandidateFit, ExperimentResiduals
from .catalogue import AMBIGUOUS, BASE, NONE, VerdictKind

THRESHOLD = 10.0


@dataclass(frozen=True, eq=False)
class NoiseFloor:
    """A test's measurement noise: its recorder's fitted noise model."""

    fit: NoiseFit

    @property
    def model(self):
        return self.fit.model

    @property
    def sigma(self) -> float:
        """Standard deviation of the noise."""
        return self.fit.model.sigma

    @property
    def phi(self) -> float:
        """Lag-1 autocorrelation of the noise (for reports)."""
        return float(self.fit.model.autocorrelation(np.array([1]))[0])

    def whiten(self, residual: np.ndarray) -> np.ndarray:
        """Standardised innovations of the valid samples (a gap breaks the chain)."""
        e = self.fit.model.whiten(np.asarray(residual, dtype=float))
        return e[np.isfinite(e)]

    def evidence(self, difference: np.ndarray) -> float:
        """What a systematic ``difference`` between two models adds to the criterion
        once its offset is profiled: its squared norm in whitened units."""
        d = np.asarray(difference, dtype=float)
        e = self.fit.model.whiten(d[None])[0]
        ones = self.fit.model.whiten(np.ones((1, d.size)))[0]
        e = e - (e @ ones) / (ones @ ones) * ones
        return float(e @ e)

    def mean_se(self, n: int) -> float:
        """Standard error of the mean of ``n`` consecutive samples."""
        k = np.arange(-(n - 1), n)
        acf = self.fit.model.autocorrelation(k)
        return float(self.sigma * np.sqrt(np.sum((n - np.abs(k)) * acf)) / n)


def noise_floors(experiments: Sequence[Experiment], fits: Mapping[str, NoiseFit] | None = None
                 ) -> dict[str, NoiseFloor]:
    """Each test's noise floor: its recorder's model, fitted to all quiet stretches of the
    recorder's tests (:func:`rapid_cosim.noise.campaign_noise`) unless ``fits`` are given."""
    fits = campaign_noise(experiments) if fits is None else fits
    return {e.name: NoiseFloor(fits[e.name]) for e in experiments}


def whitened(fit: ExperimentResiduals, floor: NoiseFloor) -> np.ndarray:
    """The test's whitened residual (valid samples): the fitness's own when it was
    whitened, else whitened here."""
    if fit.whitened is not None:
        return fit.whitened[np.isfinite(fit.whitened)]
    return floor.whiten(fit.residual)


def score(tests: Mapping[str, ExperimentResiduals], noise: Mapping[str, NoiseFloor]) -> tuple[float, int]:
    """(sum n_i log s2_i, N): the data term of the criterion and its sample count."""
    total, n_total = 0.0, 0
    for name, fit in tests.items():
        a = whitened(fit, noise[name])
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
    effect: str  # a catalogue name or the word of its kind (none, ambiguous, unexplained): see .kind
    effects: list[str] = field(default_factory=list)  # named effects, greedy order
    candidates: list[str] = field(default_factory=list)  # when ambiguous: which could not be told apart
    reason: str = ""  # why this verdict, in one clause; what later stages learn goes to notes
    held_out: dict | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def kind(self) -> VerdictKind:
        return VerdictKind.of(self.effect)

    def note(self, text: str) -> None:
        """What a later stage adds (held-out confirmation, a limit it ran into): kept
        apart, rendered once by :attr:`said`."""
        self.notes.append(text)

    @property
    def said(self) -> str:
        """The reason and every note, as the reports print it."""
        return "; ".join([self.reason, *self.notes])


def rank(fits: Sequence[CandidateFit], noise: Mapping[str, NoiseFloor]) -> list[Ranked]:
    scored = sorted(((bic(f, noise), f) for f in fits), key=lambda t: t[0])
    best = scored[0][0]
    return [Ranked(f.spec.label, f.spec.effects, b, b - best, f.fitness, f.parameters, str(f.archive))
            for b, f in scored]


def _margin(ranking: Sequence[Ranked], candidate: Ranked) -> float:
    """How much better than ``none`` the candidate is (positive: better)."""
    none = next(r for r in ranking if r.label == BASE)
    return none.bic - candidate.bic


def decisive(ranking: Sequence[Ranked], threshold: float = THRESHOLD) -> bool:
    """Whether the best candidate is an effect that beats ``none`` by the threshold."""
    best = ranking[0]
    return best.label != BASE and _margin(ranking, best) >= threshold


def decide(ranking: Sequence[Ranked], *, threshold: float = THRESHOLD,
           not_excluded: Sequence[str] = ()) -> Verdict:
    """The verdict from a ranking of single-effect candidates and ``none``.

    ``not_excluded``: effects that, held at a material size, fit within the threshold of
    ``none`` (consulted when no effect beats ``none`` decisively).
    """
    best = ranking[0]
    if not decisive(ranking, threshold):
        closest = best if best.label != BASE else ranking[1]
        support = (f"no effect improves the criterion decisively (closest: {closest.label}, "
                   f"{_margin(ranking, closest):+.1f} against the base model)")
        if not_excluded:  # a caveat, not a verdict: nothing is shown missing
            return Verdict(NONE, reason=support + "; the data cannot exclude " + ", ".join(not_excluded)
                                          + " at a material size (it fits as well as the base model with other "
                                            "parameters)")
        return Verdict(NONE, reason=support)
    margin_none = _margin(ranking, best)
    # ambiguous only between effects that each beat none decisively
    rivals = [r.label for r in ranking[1:] if r.label != BASE and r.delta < threshold
              and _margin(ranking, r) >= threshold]
    if rivals:
        return Verdict(AMBIGUOUS, candidates=[best.label, *rivals],
                       reason=f"{best.label} and {', '.join(rivals)} are within {threshold:g} of each other")
    second = ranking[1]
    caveat = f" (which does not itself beat none by {threshold:g})" if second.delta < threshold else ""
    return Verdict(best.label, effects=[best.label],
                   reason=f"{best.label} beats none by {margin_none:.1f} and the next candidate ({second.label}) by "
                          f"{second.delta:.1f}{caveat}")


def settle_on_heldout(verdict: Verdict, ranking: Sequence[Ranked], heldout_terms: Mapping[str, float],
                      threshold: float = THRESHOLD) -> Verdict:
    """An ambiguous verdict between effects, settled if training plus held-out evidence
    puts one ahead of every other by the threshold; otherwise the verdict unchanged.

    ``heldout_terms``: each tied candidate's held-out data term at its training fit.
    A tie that involves ``none`` is left alone: that is the material-size question,
    which the held-out confirmation against ``none`` answers later.
    """
    tied = verdict.candidates
    if verdict.kind is not VerdictKind.AMBIGUOUS or BASE in tied or not all(c in heldout_terms for c in tied):
        return verdict
    bics = {r.label: r.bic for r in ranking}
    total = {c: bics[c] + heldout_terms[c] for c in tied}
    order = sorted(tied, key=total.get)
    best, runner = order[0], order[1]
    lead = total[runner] - total[best]
    if lead < threshold:
        verdict.note(f"the held-out tests do not separate them either ({best} ahead of {runner} by "
                           f"{lead:.1f} over training and held-out tests)")
        return verdict
    parts = ", ".join(f"{c} by {total[c] - total[best]:.1f} (held-out {heldout_terms[c] - heldout_terms[best]:+.1f})"
                      for c in order[1:])
    margin_none = bics[BASE] - bics[best] if BASE in bics else float("nan")
    return Verdict(best, effects=[best],
                   reason=f"{best} beats none by {margin_none:.1f}; {', '.join(order[1:])} fit the training tests "
                          f"within {threshold:g} of it, but over training and held-out tests together it beats "
                          f"{parts}")
