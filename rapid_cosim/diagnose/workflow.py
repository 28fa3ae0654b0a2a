"""The discrepancy workflow: calibrate the base model, try each named effect, decide,
write the named effect into the Modelica package, compile it and re-calibrate with it.

Everything runs through the project's own machinery: candidates are archived runs of
the estimators (``candidates.py``), the verdict comes from ``selection.py``, the new
model is Modelica text from the catalogue, built like any other bench.

Kept whole (over 400 lines): the verdict's steps share one context and read in the order
they run.
"""

from __future__ import annotations

import json
import re
import shutil
from dataclasses import asdict, dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Sequence

import h5py
import numpy as np

from ..calibration import SEARCHES, RunOptions, ensure_run, log_likelihood_for
from ..compiler import build_models
from ..data import ar1_inflation
from ..errors import ConfigError, RapidCosimError
from ..estimators.laplace import laplace
from ..engine import make_engine
from ..objective import ProblemObjective
from ..experiment import Experiment
from .candidates import CandidateFit, CandidateSpec, candidate_inputs, default_start, fit_candidate, residuals_at
from .catalogue import (BASES, CATALOGUE, NONE, bench_name, camel, check_base, composable, governor, is_generated,
                        is_staged, write_bench)
from .adequacy import adequacy
from .features import Features, residual_features
from .limits import check_material, inadequate, verdict_text
from .selection import THRESHOLD, Ranked, Verdict, bic, decide, decisive, gap, pooled_noise, rank, score
from .separate import separating_test


@dataclass(frozen=True)
class DiagnoseOptions:
    method: str = "pf:10+nm"
    estimator_options: dict = field(default_factory=lambda: {"pf": {"n_particles": 40},
                                                             "nm": {"xatol": 1e-4, "fatol": 1e-10}})
    seed: int = 1
    n_jobs: int = 1
    searches: tuple[str, ...] = SEARCHES  # run besides ``method`` on every candidate, the best kept
    threshold: float = THRESHOLD
    max_effects: int = 2
    candidates: tuple[str, ...] = tuple(CATALOGUE)
    write_model: bool = True  # write the named model into the package and re-calibrate with it
    model_name: str | None = None  # class name of the model written; default from the effects

    def __post_init__(self):
        wrong = [c for c in self.candidates if c not in CATALOGUE]
        if wrong:
            raise RapidCosimError(f"candidates {', '.join(wrong)}: not in the catalogue ({', '.join(CATALOGUE)})")
        if self.max_effects < 1:
            raise RapidCosimError(f"max_effects must be at least 1, got {self.max_effects}")


def split_holdout(experiments: Sequence[Experiment], holdout: Sequence[str]) -> tuple[list, list]:
    """(training, held out) by the names of the experiments to hold out."""
    names = [e.name for e in experiments]
    unknown = [h for h in holdout if h not in names]
    if unknown:
        raise RapidCosimError(f"held-out {', '.join(unknown)}: not among the experiments ({', '.join(names)})")
    return ([e for e in experiments if e.name not in holdout], [e for e in experiments if e.name in holdout])


@dataclass
class Diagnosis:
    """The verdict with its evidence, as the JSON report holds it.

    ``effect`` is a catalogue name, ``none``, ``ambiguous`` or ``unexplained``;
    ``effects`` lists the effects named; ``adequate`` says whether the final model fits
    to the noise (:mod:`.adequacy`, per test under ``adequacy``); ``verdict`` is the
    sentence, e.g. ``"rate_limit + unexplained remainder"``."""

    effect: str
    effects: list[str]
    candidates: list[str]
    reason: str
    verdict: str
    adequate: bool
    adequacy: dict
    unexplained: dict | None
    materiality: dict
    ranking: list[dict]
    second_effect_ranking: list[dict]
    not_excluded: list[str]
    separating_test: dict | None
    held_out: dict | None
    features: dict
    gap_before: dict[str, dict]
    gap_after: dict[str, dict]
    parameters_before: dict[str, float]
    parameters_after: dict[str, float]
    parameter_intervals: dict[str, list[float]]
    noise: dict[str, dict[str, float]]
    model_written: str | None
    model_file: str | None
    archives: dict[str, str]
    training: list[str]
    heldout: list[str]
    created: str
    residuals: dict[str, dict[str, np.ndarray]] = field(default_factory=dict, repr=False)

    def to_json(self) -> dict:
        data = asdict(self)
        data.pop("residuals")
        return json.loads(json.dumps(data, default=_jsonable))

    def save(self, folder: str | Path) -> tuple[Path, Path]:
        """``diagnosis.json`` (the verdict and evidence) and ``diagnosis.h5`` (the residual
        arrays before and after, which the report plots)."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        js = folder / "diagnosis.json"
        js.write_text(json.dumps(self.to_json(), indent=2) + "\n")
        h5 = folder / "diagnosis.h5"
        with h5py.File(h5, "w") as f:
            f.attrs["effect"] = self.effect
            f.attrs["json"] = json.dumps(self.to_json())
            for test, arrays in self.residuals.items():
                g = f.create_group(test)
                for key, values in arrays.items():
                    g.create_dataset(key, data=np.asarray(values, dtype=float))
        return js, h5


def _jsonable(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


class _Context:
    """The fits made so far, by candidate label (each fitted once)."""

    def __init__(self, training, heldout, workdir, options, package, fmu_dir, log):
        self.training, self.heldout = list(training), list(heldout)
        self.workdir, self.options = Path(workdir), options
        self.user_package, self.user_fmu_dir, self.log = Path(package), Path(fmu_dir), log
        # Candidates are built from a copy of the package: combinations of effects are
        # generated there, and the user's package changes only if the verdict is written.
        self.package = self.workdir / "package" / self.user_package.name
        self.fmu_dir = self.workdir / "fmus"
        shutil.copytree(self.user_package, self.package, dirs_exist_ok=True)  # refreshed on every run
        self.noise = pooled_noise(self.training + self.heldout)
        self.fits: dict[str, CandidateFit] = {}
        self.fmus: dict = {}  # FMUs by model, built or loaded once for all candidates
        self._predictions: dict[tuple, dict] = {}
        self.run_options = RunOptions(method=options.method, seed=options.seed, n_jobs=options.n_jobs,
                                      estimator_options=options.estimator_options)

    @property
    def bases(self) -> list[str]:
        return sorted({e.model for e in self.training + self.heldout})

    def fit(self, spec: CandidateSpec, start: dict | None = None) -> CandidateFit:
        for base in self.bases:  # benches not in the package are generated into the work copy
            if is_generated(bench_name(spec.effects, base)):
                write_bench(self.package, spec.effects, bench_name(spec.effects, base), base=base,
                            description=f"{BASES[base]} with {', '.join(spec.effects)} (candidate)")
        if spec.label not in self.fits:
            self.log(f"  fitting {spec.label} ...")
            fit = fit_candidate(spec, self.training, self.workdir, options=self.run_options,
                                start=start if start is not None else default_start(spec, self.base_parameters()),
                                package=self.package, fmu_dir=self.fmu_dir, fmus=self.fmus,
                                searches=self.options.searches)
            self.fits[spec.label] = fit
            self.log(f"    fitness {fit.fitness:.4g}, BIC {bic(fit, self.noise):.1f}, {fit.nfev} evaluations")
        return self.fits[spec.label]

    def base_parameters(self) -> dict[str, float] | None:
        base = self.fits.get(NONE)
        return dict(base.parameters) if base else None

    def tests(self, fit: CandidateFit) -> dict:
        """Residuals on the training tests and, predicted, on the held-out ones."""
        return _all_tests(self, fit)

    def predict(self, fit: CandidateFit) -> dict:
        """Residuals of the held-out tests at the training calibration; kept, as the
        verdict and the report ask for the same fits more than once."""
        if not self.heldout:
            return {}
        key = (fit.spec, tuple(sorted(fit.parameters.items())))
        if key not in self._predictions:
            self._predictions[key] = self._predict(fit)
        return self._predictions[key]

    def _predict(self, fit: CandidateFit) -> dict:
        inputs = candidate_inputs(self.workdir / "heldout" / fit.spec.slug, self.heldout, fit.spec,
                                  package=self.package, fmu_dir=self.fmu_dir, fmus=self.fmus)
        x = np.array([fit.parameters[n] for n in inputs.problem.names])
        return residuals_at(inputs, x)


def diagnose(training: Sequence[Experiment], heldout: Sequence[Experiment] = (), *, workdir: str | Path,
             options: DiagnoseOptions = DiagnoseOptions(), package: str | Path = "modelica/iGrGen",
             fmu_dir: str | Path = "fmus", log: Callable[[str], None] = print) -> Diagnosis:
    if not training:
        raise ValueError("diagnose needs at least one training experiment")
    for exp in [*training, *heldout]:
        try:
            check_base(exp.model)
        except ValueError as e:
            raise ConfigError(str(e), str(exp.config_path), "experiment.model") from None
    bases = {e.model for e in [*training, *heldout]}
    apart = [c for c in options.candidates if not all(composable(c, b) for b in bases)]
    if apart:  # the valve-side effects are TG Type I variants
        log(f"not tried on {', '.join(sorted({governor(b) for b in bases}))}: {', '.join(apart)} (TG Type I variants)")
        options = replace(options, candidates=tuple(c for c in options.candidates if c not in apart))
    undocumented = [c for c in options.candidates if CATALOGUE[c].relative
                    and not all(p.name in e.fixed for e in [*training, *heldout] for p in CATALOGUE[c].parameters)]
    if undocumented:  # a constant no config documents cannot be "documented wrong"
        options = replace(options, candidates=tuple(c for c in options.candidates if c not in undocumented))
    ctx = _Context(training, heldout, workdir, options, package, fmu_dir, log)
    log(f"calibrating the base model and {len(options.candidates)} candidates on "
        f"{', '.join(e.name for e in training)}" + (f"; held out: {', '.join(e.name for e in heldout)}" if heldout else ""))
    base = ctx.fit(CandidateSpec())
    before_tests = _all_tests(ctx, base)
    features = residual_features(training + list(heldout), before_tests, ctx.noise)
    singles = [ctx.fit(CandidateSpec((name,))) for name in options.candidates]
    ranking = rank([base, *singles], ctx.noise)

    not_excluded: list[str] = []
    if not decisive(ranking, options.threshold):
        not_excluded = _material_checks(ctx, base, options)
    verdict = decide(ranking, threshold=options.threshold, not_excluded=not_excluded)
    chosen = ctx.fits[verdict.effect] if verdict.effect in ctx.fits and verdict.effect != NONE else None
    if chosen is not None and ctx.heldout:
        verdict = _confirm(ctx, chosen, base, verdict)
        if verdict.effect == "ambiguous":
            chosen = None

    second: list[Ranked] = []
    if chosen is not None and options.max_effects >= 2:
        chosen, verdict, second = _second_effect(ctx, chosen, verdict, options)

    separating = None
    if verdict.effect == "ambiguous":
        separating = _separating(ctx, verdict, not_excluded)

    materiality = {}
    if chosen is not None:
        chosen, verdict, materiality = check_material(ctx, base, chosen, verdict)

    final_fit = chosen if chosen is not None else base
    after_tests = _all_tests(ctx, final_fit)
    fit_before, fit_after = adequacy(before_tests, ctx.noise), adequacy(after_tests, ctx.noise)
    unexplained = None
    if not fit_after.adequate:
        verdict, unexplained = inadequate(ctx, verdict, ranking, before_tests, after_tests, fit_after)
        if verdict.effect == "unexplained":
            chosen = None  # a partial explanation is reported, not written into the package
    model_written, model_file = None, None
    if chosen is not None and options.write_model:
        model_written, model_file, final_fit = _write_and_recalibrate(ctx, chosen, options)
        after_tests = _all_tests(ctx, final_fit)
        fit_after = adequacy(after_tests, ctx.noise)
    gap_before = _gaps(ctx, before_tests)
    gap_after = _gaps(ctx, after_tests)
    residuals = {name: {"time": t.time, "before": t.residual, "after": after_tests[name].residual}
                 for name, t in before_tests.items()}
    return Diagnosis(
        effect=verdict.effect, effects=verdict.effects, candidates=verdict.candidates, reason=verdict.reason,
        verdict=verdict_text(verdict, fit_after), adequate=fit_after.adequate,
        adequacy={"before": fit_before.to_json(), "after": fit_after.to_json()}, unexplained=unexplained,
        materiality=materiality,
        ranking=[asdict(r) for r in ranking], second_effect_ranking=[asdict(r) for r in second],
        not_excluded=not_excluded, separating_test=separating, held_out=verdict.held_out,
        features=features.to_json(), gap_before=gap_before, gap_after=gap_after,
        parameters_before=base.parameters, parameters_after=final_fit.parameters,
        parameter_intervals=_intervals(ctx, final_fit),
        noise={name: {"sigma": f.sigma, "phi": f.phi} for name, f in ctx.noise.items()},
        model_written=model_written, model_file=model_file, residuals=residuals,
        archives={label: str(f.archive) for label, f in ctx.fits.items()},
        training=[e.name for e in training], heldout=[e.name for e in heldout],
        created=datetime.now(timezone.utc).isoformat(timespec="seconds"))


def _material_checks(ctx: _Context, base: CandidateFit, options: DiagnoseOptions) -> list[str]:
    """Effects that, held at a material size, still fit within the threshold of none."""
    base_bic = bic(base, ctx.noise)
    found = []
    # Freed documented constants are not held: the documentation stands until the data
    # contradict it, whereas an effect's absence is what "none" claims.
    for name in (c for c in options.candidates if not CATALOGUE[c].relative):
        held = tuple((p.name, p.material) for p in CATALOGUE[name].parameters)
        fit = ctx.fit(CandidateSpec((name,), held))
        # the held fit estimates no more parameters than none; compare the data terms
        if bic(fit, ctx.noise) - base_bic < options.threshold:
            found.append(name)
    return found


def _held_out_score(ctx: _Context, fit: CandidateFit) -> float:
    data_term, _ = score(ctx.predict(fit), ctx.noise)
    return data_term


def _confirm(ctx: _Context, chosen: CandidateFit, base: CandidateFit, verdict: Verdict) -> Verdict:
    named = _held_out_score(ctx, chosen)
    none = _held_out_score(ctx, base)
    improvement = none - named
    verdict.held_out = {"tests": [e.name for e in ctx.heldout], "criterion_improvement": improvement,
                        "confirmed": improvement > 0}
    if improvement <= 0:
        return Verdict("ambiguous", candidates=[verdict.effect, NONE], held_out=verdict.held_out,
                       reason=f"{verdict.effect} wins on the training tests but does not predict the held-out "
                              f"tests better than the base model ({improvement:+.1f})")
    verdict.reason += f"; confirmed on held-out {', '.join(e.name for e in ctx.heldout)} ({improvement:+.1f})"
    return verdict


def _second_effect(ctx: _Context, chosen: CandidateFit, verdict: Verdict, options: DiagnoseOptions):
    first = chosen.spec.effects
    start = dict(chosen.parameters)
    combos = []
    for name in options.candidates:
        if name in first:
            continue
        spec = CandidateSpec(first + (name,))
        combos.append(ctx.fit(spec, start=default_start(spec, start)))
    ranked = rank([chosen, *combos], ctx.noise)
    best = ranked[0]
    if best.label == chosen.spec.label:
        verdict.reason += f"; no second effect improves it (closest {ranked[1].label}, {ranked[1].delta:+.1f})"
        return chosen, verdict, ranked
    margin = next(r for r in ranked if r.label == chosen.spec.label).delta
    rivals = [r.label for r in ranked[1:] if r.label != chosen.spec.label and r.delta < options.threshold]
    if margin < options.threshold or rivals:
        verdict.reason += (f"; a second effect is not decisive ({best.label} by {margin:.1f}"
                           + (f", rivals {', '.join(rivals)})" if rivals else ")"))
        return chosen, verdict, ranked
    fit = ctx.fits[best.label]
    # Does the second effect do the work, or did the combination's search only find a
    # better optimum of the first effect's parameters? Evaluate the first effect alone
    # there; if that is about as good, the second effect is not needed (and that point,
    # if better, replaces the first effect's calibration).
    names = chosen.inputs.problem.names
    nested_tests = residuals_at(chosen.inputs, np.array([fit.parameters[n] for n in names]))
    nested = replace(chosen, parameters={n: fit.parameters[n] for n in names}, tests=nested_tests,
                     fitness=float(np.mean([t.rssd for t in nested_tests.values()])))
    nested_bic = bic(nested, ctx.noise)
    if nested_bic < bic(chosen, ctx.noise):
        chosen = ctx.fits[chosen.spec.label] = nested
    if nested_bic - bic(fit, ctx.noise) < options.threshold:
        verdict.reason += (f"; {best.label} fits better only because its search found better parameters of "
                           f"{chosen.spec.label} (the second effect adds less than {options.threshold:g})")
        return chosen, verdict, rank([chosen, *combos], ctx.noise)
    if ctx.heldout:
        named = _held_out_score(ctx, fit)
        prev = _held_out_score(ctx, chosen)
        if named >= prev:
            verdict.reason += f"; {best.label} not confirmed on the held-out tests"
            return chosen, verdict, ranked
    added = fit.spec.effects[-1]
    verdict.effects = list(fit.spec.effects)
    verdict.reason += f"; adding {added} improves it by {margin:.1f}"
    return fit, verdict, ranked


def _separating(ctx: _Context, verdict: Verdict, not_excluded: Sequence[str]) -> dict | None:
    labels = verdict.candidates
    if len(labels) < 2:
        return None
    a = ctx.fits.get(labels[0])
    other = labels[1]
    if other in not_excluded or (labels[0] == NONE and other in CATALOGUE):
        held = tuple((p.name, p.material) for p in CATALOGUE[other].parameters)
        b = ctx.fits.get(CandidateSpec((other,), held).label)
    else:
        b = ctx.fits.get(other)
    staged = [e for e in ctx.training if is_staged(e.model)]
    if a is None or b is None or not staged:
        if not staged:
            ctx.log("  no separating staged test proposed: no training experiment is a staged test to design "
                    "it from")
        return None
    return separating_test(a, b, staged[0], ctx.noise[staged[0].name])


def _write_and_recalibrate(ctx: _Context, chosen: CandidateFit, options: DiagnoseOptions):
    """The named model written into the package, compiled, and calibrated again."""
    effects = chosen.spec.effects
    held = sorted({governor(b) for b in ctx.bases} - {"TGTypeI"})  # a standard structure's name in the class
    name = options.model_name or "iGrGen.Diagnosed.Calibrated" + "".join(held) + "".join(camel(e) for e in effects)
    if not re.fullmatch(r"iGrGen\.Diagnosed\.[A-Za-z_][A-Za-z0-9_]*", name):
        raise ValueError(f"model name {name!r} must be iGrGen.Diagnosed.<Identifier>")
    values = dict(chosen.parameters)
    package_dir = ctx.user_package
    # one class per base bench: the staged test's keeps the name, a recorded-frequency one adds "Input"
    names = {base: name + ("" if is_staged(base) else "Input") for base in ctx.bases}
    targets = []
    for base, cls in names.items():
        description = (f"{BASES[base]} with {', '.join(effects)}, calibrated on "
                       f"{', '.join(e.name for e in ctx.training)} by rapid-cosim diagnose")
        targets.append(write_bench(package_dir, effects, cls, values=values, description=description, base=base))
    build_models(list(names.values()), package=package_dir, fmu_dir=ctx.user_fmu_dir, log=lambda *_: None)
    target = targets[0]
    ctx.log(f"  wrote {', '.join(map(str, targets))} and compiled; re-calibrating with it ...")
    spec = CandidateSpec(effects)
    inputs = candidate_inputs(ctx.workdir / "recalibrated", ctx.training, spec, polish_from=values, model=names,
                              package=package_dir, fmu_dir=ctx.user_fmu_dir)
    archive = ctx.workdir / "recalibrated.h5"
    result, _ = ensure_run(inputs, replace(ctx.run_options, method="nm"), archive, progress=False)
    fit = CandidateFit(spec, archive, name, result.best(), len(result.names), float(result.fun), result.nfev,
                       residuals_at(inputs, result.x), inputs=inputs)
    ctx.fits["recalibrated"] = fit
    return name, str(target), fit


def _all_tests(ctx: _Context, fit: CandidateFit) -> dict:
    """Residuals on the training tests and, predicted, on the held-out ones."""
    tests = dict(fit.tests)
    if ctx.heldout:
        tests.update(ctx.predict(fit))
    return tests


def _gaps(ctx: _Context, tests: dict) -> dict[str, dict]:
    held = {e.name for e in ctx.heldout}
    return {name: {**gap(t, ctx.noise[name]), "held_out": name in held} for name, t in tests.items()}


def _intervals(ctx: _Context, fit: CandidateFit, level: float = 0.9) -> dict[str, list[float]]:
    """90 % intervals of the calibrated parameters: Laplace's approximation of the
    Gaussian likelihood (pre-step noise levels), widened by the AR(1) variance factor
    (1 + phi) / (1 - phi), since correlated samples carry less information each."""
    problem = fit.inputs.problem
    log_likelihood = log_likelihood_for(problem)
    if log_likelihood is None:
        return {}
    objective = ProblemObjective(problem, fit.inputs.fmus, engine=make_engine(ctx.options.n_jobs))
    x = np.array([fit.parameters[n] for n in problem.names])
    try:
        approx = laplace(lambda X: -log_likelihood(objective(X)), problem.space, x, level=level)
    except RapidCosimError as e:  # intervals are evidence, not the verdict: report, do not fail
        ctx.log(f"  no parameter intervals: {e}")
        return {}
    inflation = float(np.mean([ar1_inflation(ctx.noise[e.name].phi) for e in problem.experiments]))
    z = approx.interval - approx.mean[:, None]
    out = {}
    for k, name in enumerate(problem.names):
        half = np.sqrt(inflation) * (z[k, 1] if np.isfinite(z[k, 1]) else np.inf)
        out[name] = [float(x[k] - half), float(x[k] + half)]
    return out


__all__ = ["DiagnoseOptions", "Diagnosis", "Features", "diagnose"]
