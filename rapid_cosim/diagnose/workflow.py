"""The discrepancy workflow: calibrate the base model, try each named effect, decide,
write the named effect into the Modelica package, compile it and re-calibrate with it.

Everything runs through the project's own machinery: the recorder's noise model from the
quiet data (:mod:`rapid_cosim.noise`), candidates that are archived multistart runs
(:mod:`.candidates`, :mod:`.context`), the verdict from :mod:`.selection`, its adequacy
against a computed null (:mod:`.adequacy`), the new model as Modelica text from the
catalogue, built like any other bench.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..calibration import ensure_run
from ..compiler.source import ModelSource
from ..errors import ConfigError
from ..estimators.profile import grid, profile
from ..fitting.objective import ProblemObjective
from ..experiment import Experiment
from .adequacy import jitter_share
from .candidates import CandidateFit, CandidateSpec, candidate_inputs, default_start, residuals_at
from .catalogue import BASE, BASES, CATALOGUE, NONE, VerdictKind, camel, check_base, composable, effect_parameters, governor, is_staged, \
    write_bench
from .context import Context, DiagnoseOptions, split_holdout
from .null import KeptReplicates
from .features import Features, residual_features
from .intervals import exchanged, intervals
from .limits import check_material, inadequate, verdict_text
from .result import AdequacyJudgement, Advice, Diagnosis, DiagnosisVerdict, SearchReport
from .selection import Ranked, Verdict, bic, decide, decisive, gap, rank, score, settle_on_heldout
from .advice import advise
from .starts import search_certainty
from .variants import check_variants



def diagnose(training: Sequence[Experiment], heldout: Sequence[Experiment] = (), *, workdir: str | Path,
             options: DiagnoseOptions = DiagnoseOptions(), source: ModelSource = ModelSource(),
             log: Callable[[str], None] = print,
             noise_fits: dict | None = None, kept: KeptReplicates | None = None) -> Diagnosis:
    """Name what the base model misses on ``training`` (confirmed on ``heldout``), or say
    that nothing in the catalogue does; see the package docstring for the steps.
    ``noise_fits``: the recorders' noise fits of these experiments, where the caller has
    them already (an identification shares one fit between its two parts); ``kept``: the
    noise replicates it shares likewise (:class:`~.null.KeptReplicates`)."""
    options = _tried(training, heldout, options, log)
    ctx = Context(training, heldout, workdir, options, source, log, noise_fits, kept)
    for fit in {id(f): f for f in ctx.noise_fits.values()}.values():
        log(f"noise of the recorder of {', '.join(fit.tests)} ({fit.n_stretches} quiet stretches, {fit.n_samples} "
            f"samples): {fit.model.describe()}")
    log(f"calibrating the base model and {len(options.candidates)} candidates on "
        f"{', '.join(e.name for e in training)}" + (f"; held out: {', '.join(e.name for e in heldout)}" if heldout else ""))
    base = ctx.fit(CandidateSpec())
    before_tests = ctx.tests(base)
    features = residual_features(training + list(heldout), before_tests, ctx.noise)
    singles = ctx.fit_many([(CandidateSpec((name,)), None) for name in options.candidates])
    ranking = rank([base, *singles], ctx.noise)

    n = _name(ctx, base, ranking, options)
    verdict, chosen, not_excluded, second, variants, story, separating, materiality = (
        n.verdict, n.chosen, n.not_excluded, n.second, n.variants, n.story, n.separating, n.materiality)

    final_fit = chosen if chosen is not None else story if story is not None else base
    after_tests = ctx.tests(final_fit)
    fit_before, fit_after = ctx.adequacy(base), ctx.adequacy(final_fit)
    unexplained = None
    if not fit_after.adequate:
        verdict, unexplained = inadequate(ctx, verdict, ranking, before_tests, after_tests, fit_after)
        if verdict.kind is VerdictKind.UNEXPLAINED:
            chosen = None  # a partial explanation is reported, not written into the package
    model_written, model_file = None, None
    if chosen is not None and options.write_model:
        model_written, model_file, final_fit = _write_and_recalibrate(ctx, chosen, options)
        after_tests = ctx.tests(final_fit)
        fit_after = ctx.adequacy(final_fit)
    judged = {label: ctx.adequacy(ctx.fits[label]) for label in options.judge if label in ctx.fits}
    judged.update({"final": fit_after, "base": fit_before})
    search = search_certainty(ctx.fits, verdict, [*ranking, *second], options.threshold)
    if search.uncertain:
        verdict.note(search.warning)
    gap_before = _gaps(ctx, before_tests)
    gap_after = _gaps(ctx, after_tests)
    bands = intervals(final_fit, engine=ctx.options.engine.local(), log=ctx.log)
    residuals = {name: {"time": t.time, "before": t.residual, "after": after_tests[name].residual,
                        "whitened_before": t.whitened, "whitened_after": after_tests[name].whitened}
                 for name, t in before_tests.items()}
    named = DiagnosisVerdict(verdict.effect, verdict.effects, verdict.candidates, verdict.said,
                             verdict_text(verdict, fit_after), not_excluded, separating, verdict.held_out)
    found = features.to_json()
    exchanged_bands = exchanged(final_fit, bands, ctx.noise)
    noise_report = _noise_report(ctx)
    searched = SearchReport(ranking, second, search, _profiles(ctx, final_fit), variants)
    return Diagnosis(
        named, AdequacyJudgement(fit_before, fit_after, judged, unexplained, materiality), searched,
        features=found, gap_before=gap_before, gap_after=gap_after,
        parameters_before=base.parameters, parameters_after=final_fit.parameters,
        parameter_intervals=bands, exchanged_intervals=exchanged_bands,
        noise=noise_report, timing=jitter_share(after_tests, ctx.noise),
        model_written=model_written, model_file=model_file, residuals=residuals,
        archives={label: str(f.archive) for label, f in ctx.fits.items()},
        training=[e.name for e in training], heldout=[e.name for e in heldout],
        created=datetime.now(timezone.utc).isoformat(timespec="seconds"))


def _tried(training: Sequence[Experiment], heldout: Sequence[Experiment], options: DiagnoseOptions,
           log: Callable[[str], None]) -> DiagnoseOptions:
    """The options with the candidates that can be tried on these benches: the
    experiments checked, TG Type I's valve-side variants left out on other governors, a
    documented constant no config documents left out (it cannot be "documented wrong")."""
    if not training:
        raise ConfigError("diagnose needs at least one training experiment (none given, or every one held out)")
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
    if undocumented:
        options = replace(options, candidates=tuple(c for c in options.candidates if c not in undocumented))
    return options


@dataclass
class _Named:
    """What naming the effect found: the verdict, the fit chosen (None: none, ambiguous or
    unconfirmed) and what the steps on the way kept."""

    verdict: Verdict
    chosen: CandidateFit | None
    not_excluded: list[str]
    second: list[Ranked]
    variants: dict
    story: CandidateFit | None  # the simpler of two stories the data cannot tell apart
    separating: Advice | None
    materiality: dict


def _name(ctx: Context, base: CandidateFit, ranking: list[Ranked], options: DiagnoseOptions) -> _Named:
    """The verdict from the ranking: the material checks of none, the held-out tests on a
    tie and on the chosen effect, a second effect, the variants of form, the separating
    test of an ambiguous verdict or of a caveat, the materiality of what is named."""
    not_excluded: list[str] = []
    if not decisive(ranking, options.threshold):
        not_excluded = _material_checks(ctx, base, options)
    verdict = decide(ranking, threshold=options.threshold, not_excluded=not_excluded)
    if verdict.kind is VerdictKind.AMBIGUOUS and ctx.heldout and BASE not in verdict.candidates:
        verdict = settle_on_heldout(verdict, ranking, {c: _held_out_score(ctx, ctx.fits[c])
                                                       for c in verdict.candidates if c in ctx.fits},
                                    options.threshold)
    chosen = ctx.fits[verdict.effect] if verdict.kind is VerdictKind.NAMED and verdict.effect in ctx.fits else None
    if chosen is not None and ctx.heldout:
        verdict = _confirm(ctx, chosen, base, verdict)
        if verdict.kind is VerdictKind.NONE:  # not confirmed: a caveat of none, not a verdict
            not_excluded = [*not_excluded, chosen.spec.label]
            chosen = None
    second: list[Ranked] = []
    if chosen is not None and options.max_effects >= 2:
        chosen, verdict, second = _second_effect(ctx, chosen, verdict, options)
    variants, story = {}, None
    if chosen is not None:
        chosen, verdict, variants, story = check_variants(ctx, chosen, verdict, options.threshold)
        if verdict.kind is VerdictKind.AMBIGUOUS:
            chosen = None
    separating = None
    if verdict.kind is VerdictKind.AMBIGUOUS:
        separating = _separating(ctx, verdict.candidates, not_excluded)
    elif verdict.kind is VerdictKind.NONE and not_excluded:  # the staged test that would tell none from the caveat
        separating = _separating(ctx, [BASE, not_excluded[0]], not_excluded)
        if separating:
            verdict.note(separating.words)
    materiality = {}
    if chosen is not None:
        chosen, verdict, materiality = check_material(ctx, base, chosen, verdict)
    return _Named(verdict, chosen, not_excluded, second, variants, story, separating, materiality)


def _material_checks(ctx: Context, base: CandidateFit, options: DiagnoseOptions) -> list[str]:
    """Effects that, held at a material size, still fit within the threshold of none."""
    base_bic = bic(base, ctx.noise)
    found = []
    # Freed documented constants are not held: the documentation stands until the data
    # contradict it, whereas an effect's absence is what "none" claims.
    names = [c for c in options.candidates if not CATALOGUE[c].relative]
    held = [CandidateSpec((name,), tuple((p.name, p.material) for p in CATALOGUE[name].parameters)) for name in names]
    for name, fit in zip(names, ctx.fit_many([(spec, None) for spec in held])):
        # the held fit estimates no more parameters than none; compare the data terms
        if bic(fit, ctx.noise) - base_bic < options.threshold:
            found.append(name)
    return found


def _held_out_score(ctx: Context, fit: CandidateFit) -> float:
    data_term, _ = score(ctx.predict(fit), ctx.noise)
    return data_term


def _confirm(ctx: Context, chosen: CandidateFit, base: CandidateFit, verdict: Verdict) -> Verdict:
    named = _held_out_score(ctx, chosen)
    none = _held_out_score(ctx, base)
    improvement = none - named
    verdict.held_out = {"tests": [e.name for e in ctx.heldout], "criterion_improvement": improvement,
                        "confirmed": improvement > 0}
    if improvement <= 0:
        return Verdict(NONE, held_out=verdict.held_out,
                       reason=f"{verdict.effect} wins on the training tests but does not predict the held-out "
                              f"tests better than the base model ({improvement:+.1f}): not named, not excluded")
    verdict.note(f"confirmed on held-out {', '.join(e.name for e in ctx.heldout)} ({improvement:+.1f})")
    return verdict


def _second_effect(ctx: Context, chosen: CandidateFit, verdict: Verdict, options: DiagnoseOptions):
    first = chosen.spec.effects
    start = dict(chosen.parameters)
    specs = [CandidateSpec(first + (name,)) for name in options.candidates if name not in first]
    combos = ctx.fit_many([(spec, default_start(spec, start)) for spec in specs])
    ranked = rank([chosen, *combos], ctx.noise)
    best = ranked[0]
    if best.label == chosen.spec.label:
        verdict.note(f"no second effect improves it (closest {ranked[1].label}, {ranked[1].delta:+.1f})")
        return chosen, verdict, ranked
    margin = next(r for r in ranked if r.label == chosen.spec.label).delta
    rivals = [r.label for r in ranked[1:] if r.label != chosen.spec.label and r.delta < options.threshold]
    if margin < options.threshold or rivals:
        verdict.note(f"a second effect is not decisive ({best.label} by {margin:.1f}"
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
        verdict.note(f"{best.label} fits better only because its search found better parameters of "
                           f"{chosen.spec.label} (the second effect adds less than {options.threshold:g})")
        return chosen, verdict, rank([chosen, *combos], ctx.noise)
    if ctx.heldout:
        named = _held_out_score(ctx, fit)
        prev = _held_out_score(ctx, chosen)
        if named >= prev:
            verdict.note(f"{best.label} not confirmed on the held-out tests")
            return chosen, verdict, ranked
    added = fit.spec.effects[-1]
    verdict.effects = list(fit.spec.effects)
    verdict.note(f"adding {added} improves it by {margin:.1f}")
    return fit, verdict, ranked


def _separating(ctx: Context, labels: Sequence[str], not_excluded: Sequence[str]) -> Advice | None:
    """The advice on the next test among ``labels`` (best first); a caveat not excluded,
    or an effect against the base model, is taken at its material size."""
    if len(labels) < 2:
        return None
    fits = [ctx.fits.get(labels[0])]
    for other in labels[1:]:
        b = None
        if other in not_excluded or (labels[0] == BASE and other in CATALOGUE):
            held = tuple((p.name, p.material) for p in CATALOGUE[other].parameters)
            b = ctx.fits.get(CandidateSpec((other,), held).label)  # at its material size
        fits.append(b or ctx.fits.get(other))
    staged = [e for e in ctx.training if is_staged(e.model)]
    if any(f is None for f in fits) or not staged:
        if not staged:
            ctx.log("  no separating staged test proposed: no training experiment is a staged test to design "
                    "it from")
        return None
    return advise(fits, staged[0], ctx.noise[staged[0].name], seed=ctx.options.seed or 0)


def written_into(ctx) -> tuple[Path, str]:
    """The package a named model is written into, and why not the user's where it is not:
    the user's own package (``--package``, ``$RAPID_COSIM_PACKAGE``) where it can be
    written; else the work folder's copy, never the package shipped inside rapid_cosim
    (an installed wheel's files are not the user's to change)."""
    copy, users = ctx.source.package, ctx.user_source.package_path
    if not ctx.user_source.users_package:
        return copy, (f"the model goes into the work folder's copy of the shipped package, {copy} "
                      "(--package names a package of yours to write it into)")
    if not os.access(users / "Diagnosed", os.W_OK):
        return copy, (f"{users} cannot be written: the model goes into the work folder's copy, "
                      f"{copy} (--package names a package of yours)")
    return users, ""


def _write_and_recalibrate(ctx: Context, chosen: CandidateFit, options: DiagnoseOptions):
    """The named model written into the package, compiled, and calibrated again."""
    effects = chosen.spec.effects
    held = sorted({governor(b) for b in ctx.bases} - {"TGTypeI"})  # a standard structure's name in the class
    name = options.model_name or "iGrGen.Diagnosed.Calibrated" + "".join(held) + "".join(camel(e) for e in effects)
    values = dict(chosen.parameters)
    package_dir, why = written_into(ctx)
    if why:
        ctx.log(f"  {why}")
    # one class per base bench: the staged test's keeps the name, a recorded-frequency one adds "Input"
    names = {base: name + ("" if is_staged(base) else "Input") for base in ctx.bases}
    targets = []
    for base, cls in names.items():
        description = (f"{BASES[base]} with {', '.join(effects)}, calibrated on "
                       f"{', '.join(e.name for e in ctx.training)} by rapid-cosim diagnose")
        targets.append(write_bench(package_dir, effects, cls, values=values, description=description, base=base))
    written = replace(ctx.user_source, package=package_dir)
    written.build(list(names.values()))
    target = targets[0]
    ctx.log(f"  wrote {', '.join(map(str, targets))} and compiled; re-calibrating with it ...")
    spec = CandidateSpec(effects)
    inputs = candidate_inputs(ctx.workdir / "recalibrated", ctx.training, spec, polish_from=values, model=names,
                              source=written, noise=ctx.models)
    archive = ctx.workdir / "recalibrated.h5"
    result, _ = ensure_run(inputs, replace(ctx.run_options, method="nm"), archive, progress=False,
                           replace_stale=True)
    fit = CandidateFit(spec, archive, name, result.best(), len(result.names), float(result.fun), result.nfev,
                       residuals_at(inputs, result.x), inputs=inputs)
    ctx.fits["recalibrated"] = fit
    return name, str(target), fit


def _gaps(ctx: Context, tests: dict) -> dict[str, dict]:
    held = {e.name for e in ctx.heldout}
    return {name: {**gap(t, ctx.noise[name]), "held_out": name in held} for name, t in tests.items()}


PROFILE_POINTS = 12


def _profiles(ctx: Context, fit: CandidateFit) -> dict:
    """Profile likelihoods of the named effects' parameters at the final fit: each held at
    :data:`PROFILE_POINTS` values over its range (and its optimum), the others refitted;
    in criterion units above the optimum, with the 90 % likelihood-ratio interval."""
    names = [p.name for p in effect_parameters(fit.spec.effects) if p.name in fit.parameters]
    if not names or fit.inputs is None:
        return {}
    problem = fit.inputs.problem
    objective = ProblemObjective(problem, fit.inputs.fmus, engine=ctx.options.engine.local().make())
    x = np.array([fit.parameters[n] for n in problem.names])
    n_samples = fit.n_samples
    out = {}
    for name in names:
        k = problem.names.index(name)
        prof = profile(objective, problem.space, x, k, grid(problem.space, k, PROFILE_POINTS, around=x[k]),
                       rng=np.random.default_rng(ctx.options.seed))
        f_best = min(float(np.min(prof.fitness)), fit.fitness)
        lo, hi = prof.interval(n_samples)
        out[name] = {"values": prof.values.tolist(), "delta_bic": (n_samples * np.log(prof.fitness / f_best)).tolist(),
                     "optimum": float(x[k]), "interval_90": [lo, hi], "log_scale": bool(problem.space.log[k])}
        if np.min(prof.fitness) < fit.fitness * np.exp(-2.0 / n_samples):
            ctx.log(f"  the profile of {name} found a better point than the search ({n_samples * np.log(fit.fitness / np.min(prof.fitness)):.1f} "
                    "in BIC): the search was not certified")
            out[name]["better_than_search"] = True
    return out


def _noise_report(ctx: Context) -> dict:
    """Each recorder's noise model with its uncertainty and quiet-data autocorrelation."""
    recorders = {id(f): f for f in ctx.noise_fits.values()}
    return {"recorders": [f.to_json() for f in recorders.values()],
            "tests": {name: {"sigma": floor.sigma, "phi": floor.phi, "recorder": list(recorders).index(id(floor.fit))}
                      for name, floor in ctx.noise.items()}}


__all__ = ["DiagnoseOptions", "Diagnosis", "Features", "diagnose", "split_holdout"]
