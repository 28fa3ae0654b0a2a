"""Which governor structure fits a unit: TG Type I, TGOV1, IEEEG1, GGOV1, HYGOV (iGrGen.Governors),
each calibrated jointly on the training tests and ranked by the rules the effects obey.

A structure is a small TOML file (:mod:`.structure`); each test keeps its data, source,
dispatch, fitness and simulation settings, its governor constants and estimates the
structure's.

Ranking: BIC on residuals whitened by the recorder's noise model (:mod:`.selection`,
:mod:`rapid_cosim.noise`), one offset per test counted; every structure is fitted by
the whitened least squares it is judged by. A structure is named when it beats every other by the threshold (10), or every
one within the threshold estimates more parameters than it (a richer structure must win
by the threshold, as an effect must over ``none``: the standard models nearly nest each
other, and the richer one's extra freedom always buys a little), the held-out tests do
not take that back (the criterion over training and held-out tests together, held-out
ones predicted, still favours it by as much: one held-out test that the runner-up
predicts better by under one unit is noise, not a contradiction of 20 units of training
evidence), and is adequate (:mod:`.adequacy`); otherwise
the verdict is ``ambiguous`` between those within the threshold, or ``unexplained`` when
none fits to the noise (adequacy against its computed null, :mod:`.adequacy`). Each
structure is calibrated by the run's method (multistart least squares, ``ms``, by
default) and by ``searches`` if given, the best fit kept (:mod:`.calibrations`; an
optional variant screened from its structure's optimum first). Each structure's
identifiability at its optimum comes with it (:mod:`.identifiability`).

Structures and effects combine: :func:`effects_on` runs the effect catalogue on the
winning structure (:attr:`StructureVerdict.winner`: the one named, or the first by the
threshold when none fits alone). On a standard structure only the frequency-path and
output effects are composed; the valve-side ones are TG Type I variants, and the
standard models carry valve limits among their own parameters.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..calibration import RunOptions, inputs_from_experiments
from ..compiler.source import ModelSource
from ..experiment import EstimateSpec, Experiment
from ..simulator import get_simulator
from ..diagnose.adequacy import TestAdequacy
from ..diagnose.catalogue import AMBIGUOUS, UNEXPLAINED, VerdictKind
from ..diagnose.candidates import residuals_at
from ..diagnose.judging import Judge, jacobians_at
from .calibrations import Calibrations, start_checked
from .identifiability import DeterminingStep, Identifiability, best_separating_step, identifiability
from .structure import Structure, on_structure
from ..diagnose.null import KeptReplicates
from ..diagnose.selection import THRESHOLD, score
from ..diagnose.separate import SeparatingStep, separating_menu

@dataclass
class StructureFit:
    name: str
    bic: float
    delta: float
    fitness: float
    parameters: dict[str, float]
    n_estimated: int
    adequate: bool
    variance_ratio: float
    heldout_score: float | None
    identifiability: Identifiability | None  # at the optimum (None: not computed)
    separating_step: DeterminingStep | None
    archive: str
    at_bounds: list[str] = field(default_factory=list)  # estimates that ended on a bound of their range
    tests: dict[str, TestAdequacy] = field(default_factory=dict)  # per test, its adequacy
    data_term: float | None = None  # the BIC less its k ln n: two nested fits' difference is their likelihood ratio

    def to_json(self) -> dict:
        """As structures.json holds it (each test's adequacy under its name)."""
        return {**asdict(self), "identifiability": self.identifiability.to_json() if self.identifiability else {},
                "separating_step": self.separating_step.to_json() if self.separating_step else None,
                "tests": {name: t.to_json() for name, t in self.tests.items()}}


@dataclass
class StructureVerdict:
    structure: str  # a name, or the word of its kind (ambiguous, unexplained): see .kind
    candidates: list[str]
    reason: str
    ranking: list[StructureFit] = field(default_factory=list)
    effects: dict | None = None  # the effect catalogue's verdict on the winning structure
    separating_test: SeparatingStep | None = None  # when ambiguous: the staged test that would tell the first two apart

    @property
    def kind(self) -> VerdictKind:
        return VerdictKind.of(self.structure)

    @property
    def winner(self) -> str | None:
        """The structure the effect catalogue runs on: the one named, or, when none fits
        to the noise, the first if it beats every other by the threshold (what is missing
        may be an effect on top of it)."""
        if self.kind is VerdictKind.NAMED:
            return self.structure
        if self.kind is VerdictKind.UNEXPLAINED and (len(self.ranking) == 1 or self.ranking[1].delta >= THRESHOLD):
            return self.ranking[0].name
        return None

    def to_json(self) -> dict:
        return {"structure": self.structure, "candidates": self.candidates, "reason": self.reason,
                "ranking": [r.to_json() for r in self.ranking], "effects": self.effects,
                "separating_test": self.separating_test.to_json() if self.separating_test else None}


def effects_on(structure: Structure, training: Sequence[Experiment], heldout: Sequence[Experiment], *,
               workdir: str | Path, options, source: ModelSource, log: Callable[[str], None] = print) -> dict:
    """The effect catalogue on ``structure`` (frequency-path and output effects on a
    standard structure; all of them on TG Type I): the diagnosis's verdict, in short."""
    from ..diagnose.workflow import diagnose

    d = diagnose([structure.experiment(e) for e in training], [structure.experiment(e) for e in heldout],
                 workdir=workdir, options=options, source=source, log=log)
    n = d.named
    return {"structure": structure.name, "effect": n.effect, "effects": n.effects, "verdict": n.verdict,
            "adequate": d.adequate, "candidates": n.candidates, "reason": n.reason,
            "ranking": [{"label": r.label, "delta": r.delta, "parameters": r.parameters}
                        for r in d.searched.ranking],
            "variance_ratio_after": d.adequacy.after.pooled_variance_ratio}




def select_structure(structures: Sequence[Structure], training: Sequence[Experiment],
                     heldout: Sequence[Experiment] = (), *, workdir: str | Path, options: RunOptions,
                     source: ModelSource = ModelSource(), threshold: float = THRESHOLD, searches: Sequence[str] = (), fitted_noise: dict | None = None,
                     log: Callable[[str], None] = print, kept: KeptReplicates | None = None,
                     calibrations: "Calibrations | None" = None) -> StructureVerdict:
    """Calibrate every structure on ``training`` by ``options.method`` and each of
    ``searches`` (the best kept), rank them and give the verdict. ``fitted_noise``: the
    campaign's :func:`~rapid_cosim.noise.campaign_noise` when the caller has it already;
    ``kept``: the noise replicates the caller made with it (its explanation's), taken
    where the tests are the same (:class:`~rapid_cosim.diagnose.null.KeptReplicates`);
    ``calibrations``: these structures' calibrations, started by the caller before."""
    workdir = Path(workdir)
    judging = Judge.of([*training, *heldout], fitted_noise)
    fitted_noise, noise = judging.noise_fits, judging.floors
    fits = []
    log(f"  calibrating {', '.join(s.name for s in structures)} ...")
    runs = start_checked(calibrations, structures, training, fitted_noise, options, workdir, searches,
                         source).runs()
    for s, (result, archive) in zip(structures, runs):
        exps = on_structure(s, training, fitted_noise)
        inputs = inputs_from_experiments(exps, source=source)
        tests = residuals_at(inputs, result.x)
        data_term, n = score(tests, noise)
        k = len(result.names) + len(tests)
        held_score, parts = None, [(inputs, result.x)]
        held_inputs = None
        if heldout:
            held_inputs = inputs_from_experiments(on_structure(s, heldout, fitted_noise), source=source)
            best = result.best()
            x = np.array([best[name] for name in held_inputs.problem.names])
            held_tests = residuals_at(held_inputs, x)
            held_score = float(score(held_tests, noise)[0])
            tests.update(held_tests)
            parts.append((held_inputs, x))
        judging.replicate([*inputs.experiments, *(held_inputs.experiments if held_inputs else ())],
                          seed=options.seed, kept=kept, engine=options.engine)
        fit_ok = judging.judge(tests, jacobians_at(*parts), [e.name for e in training])
        ident = identifiability(inputs, np.asarray(result.x), noise)
        step = best_separating_step(inputs, np.asarray(result.x), ident, noise)
        fits.append(StructureFit(s.name, data_term + k * np.log(n), 0.0, float(result.fun), result.best(),
                                 len(result.names), fit_ok.adequate, fit_ok.pooled_variance_ratio, held_score,
                                 ident, step, str(archive),
                                 _at_bounds(s.estimate, result.best()), {t.test: t for t in fit_ok.tests},
                                 float(data_term)))
        log(f"  {s.name} ({', '.join(s.estimate)}): BIC {fits[-1].bic:.1f}, variance ratio "
            f"{fit_ok.pooled_variance_ratio:.2f}, {ident.summary()}")
    fits.sort(key=lambda f: f.bic)
    for f in fits:
        f.delta = f.bic - fits[0].bic
    verdict = _verdict(fits, threshold)
    staged = [e for e in training if not e.inputs]  # a step test to design the next one from
    if verdict.kind is VerdictKind.AMBIGUOUS and staged:
        a, b = (next(s for s in structures if s.name == n) for n in verdict.candidates[:2])
        verdict.separating_test = _separating(a, b, fits, staged[0], noise, source)
        log(f"  {verdict.separating_test.advice}")
    return verdict


def _separating(a: Structure, b: Structure, fits: list[StructureFit], template: Experiment, noise,
                source: ModelSource) -> SeparatingStep:
    """The staged test that would tell structures ``a`` and ``b`` apart, from their fits."""
    def model(s: Structure) -> tuple[str, object, dict]:
        exp = s.experiment(template)
        fmu = inputs_from_experiments([exp], source=source).fmus[exp.model]
        fit = next(f for f in fits if f.name == s.name)
        return s.name, get_simulator(fmu), {**exp.fixed, **fit.parameters}

    return separating_menu(model(a), model(b), template, noise[template.name])


def _at_bounds(estimate: dict[str, EstimateSpec], best: dict[str, float], share: float = 0.01) -> list[str]:
    """Estimates within ``share`` of their range (in the log for log-scaled ones) of a
    bound: the range, or the structure, holds them there."""
    out = []
    for name, spec in estimate.items():
        lo, hi, x = spec.min, spec.max, best[name]
        if spec.scale == "log":
            lo, hi, x = np.log(lo), np.log(hi), np.log(x)
        if min(x - lo, hi - x) <= share * (hi - lo):
            out.append(f"{name} = {best[name]:.4g} at its {'lower' if x - lo < hi - x else 'upper'} bound")
    return out


def _verdict(fits: list[StructureFit], threshold: float) -> StructureVerdict:
    """The structure verdict from the fits in BIC order (the rules of the module docstring)."""
    top = fits[0]
    # A richer structure must beat a simpler one by the threshold, as an effect must beat
    # none: a simpler structure within it of the first ties with it, and is named.
    simpler = sorted((f for f in fits[1:] if f.delta < threshold and f.n_estimated < top.n_estimated),
                     key=lambda f: (f.n_estimated, f.bic))
    best = simpler[0] if simpler else top
    others = [f for f in fits if f is not best]
    close = [f for f in others if f.delta - best.delta < threshold]
    richer = [f.name for f in close if f.n_estimated > best.n_estimated]
    rivals = [f.name for f in close if f.n_estimated == best.n_estimated]
    if not any(f.adequate for f in fits):
        margin = f", by {fits[1].delta:.1f} in BIC over {fits[1].name}" if len(fits) > 1 else ""
        return StructureVerdict(UNEXPLAINED, [f.name for f in fits],
                                f"no structure fits to the noise (best {top.name}{margin}, variance ratio "
                                f"{top.variance_ratio:.2f}): what is missing is missing from every structure "
                                "tried, or is another structure", fits)
    if rivals:
        return StructureVerdict(AMBIGUOUS, [best.name, *rivals],
                                f"{best.name} and {', '.join(rivals)}, as simple, are within {threshold:g} in BIC",
                                fits)
    beaten = [f for f in others if f.name not in richer]
    clauses = [f"{best.name} beats {beaten[0].name} by {beaten[0].delta - best.delta:.1f} in BIC" if beaten
               else f"{best.name} is the only structure tried" if len(fits) == 1 else f"{best.name} is first"]
    if best is not top:
        clauses.insert(0, f"{best.name} ties with {top.name} ({best.delta:.1f} behind it in BIC, within {threshold:g}, "
                          "with fewer estimated parameters, which it names)")
    if richer:
        clauses.append(f"{', '.join(richer)} come within {threshold:g} with more estimated parameters, "
                       "which they do not earn")
    runner = others[0] if others else None
    if best.heldout_score is not None and runner is not None and runner.heldout_score is not None:
        # The held-out tests are more evidence of the same kind (the criterion's data term
        # on tests the fit never saw): added to the training evidence they can name a richer
        # runner that then beats the named one by the threshold, or leave an as-simple or
        # simpler one within it (ambiguous).
        held = runner.heldout_score - best.heldout_score  # positive: the held-out tests agree
        gap = runner.delta - best.delta  # training evidence for best over the runner (negative in a tie)
        if held > 0:
            clauses.append(f"confirmed on the held-out tests ({held:+.1f})")
        elif runner.name in richer and gap + held <= -threshold:
            return StructureVerdict(runner.name, [runner.name, best.name],
                                    f"{runner.name} beats {best.name} by {-(gap + held):.1f} over training and "
                                    f"held-out tests together ({-gap:.1f} on training, {-held:.1f} held out), "
                                    "which earns its extra parameters", fits)
        elif runner.name not in richer and gap + held < threshold:
            return StructureVerdict(AMBIGUOUS, [best.name, runner.name],
                                    "; ".join(clauses) + f", but predicts the held-out tests worse than "
                                    f"{runner.name} ({held:+.1f}), which leaves {gap + held:.1f} over all tests",
                                    fits)
        else:
            clauses.append(f"the held-out tests favour {runner.name} by {-held:.1f}, less than the training "
                           f"evidence ({gap + held:.1f} left over all tests)")
    if not best.adequate:
        clauses.append(f"it does not fit to the noise (variance ratio {best.variance_ratio:.2f}): an unexplained "
                       "remainder")
    ties = [best.name, top.name] if best is not top else [best.name]
    return StructureVerdict(best.name, ties, "; ".join(clauses), fits)
