"""Confusion matrix of the discrepancy workflow on synthetic campaigns with realistic
recorder noise (``make bench-diagnose``).

Plants, effects and recorders are invented in :mod:`rapid_cosim.diagnose.campaigns`
(white plus slow noise, 0-5 ms jitter, 16-bit quantisation). Per seed: every physical
effect of the catalogue hidden in a staged campaign (the field's tests 2, 9, 10 and,
held out, 4) and in an event campaign (three recorded grid events at 50 frames/s, the
last held out; the rate limit asymmetric, its opening limit binding all through the
rise); a documented T4 or T5 off by a factor 2; the two variants of form (a load
controller on filtered power, a rate limit on the governor's command); two pairs of
effects; two effects outside the catalogue. Plus ``--null-seeds`` effect-free staged
campaigns (100 by default) and a campaign with one step size and a deadband, where the
right answer is ``ambiguous``.

Prints the matrix and the rates the trust issue asks for: effect-free ``none`` and
adequate, the true model judged adequate, foreign effects ``unexplained``, single
effects named on staged tests and on events, documentation blamed for a variant of form,
candidates whose optimum was not certified, and, on the event rate-limit campaigns,
whether the rate-limit fit reached the best point (checked by a local fit from the
plant's true parameters). Cases run in parallel processes (``--n-jobs``).
"""

from __future__ import annotations

import argparse
import pickle
import shutil
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import joblib
import numpy as np
from rapid_cosim.compiler.source import ModelSource

ROOT = Path(__file__).resolve().parents[1]
PAIRS = ("rate_limit+load_controller", "deadband+measurement_lag")
VARIANTS = ("load_controller_filtered", "rate_limit_command")


def _seeds(spec: str) -> list[int]:
    out = []
    for part in filter(None, spec.split(",")):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def _truth_labels(truth: str) -> tuple[str, ...]:
    parts = truth.split("+")
    return tuple({truth, "+".join(reversed(parts))}) if len(parts) == 2 else (truth,)


def _reached_from_truth(result) -> float | None:
    """For an event rate-limit campaign: criterion difference between the rate-limit
    candidate's multistart best and a local fit from the plant's true parameters
    (positive: the local fit found a better point, the search missed it)."""
    from rapid_cosim.calibration import inputs_from_archive
    from rapid_cosim.archive import RunArchive
    from rapid_cosim.estimators.base import Tracker
    from rapid_cosim.estimators.lm import LMOptions, levenberg_marquardt
    from rapid_cosim.fitting.objective import ProblemObjective

    archive = result.diagnosis.archives.get("rate_limit")
    if archive is None:
        return None
    with RunArchive(archive) as view:
        inputs = inputs_from_archive(view)
        best = view.result()
    problem = inputs.problem
    truth = {**result.case.plant, **result.case.effect_values}
    x = problem.space.clip(np.array([truth[n] for n in problem.names]))
    t = Tracker("check", ProblemObjective(problem, inputs.fmus), problem.space, np.random.default_rng(0), None)
    run = levenberg_marquardt(t, np.clip(problem.space.to_unit(x), 0, 1)[None], LMOptions())
    n = sum(int(np.sum(np.isfinite(v))) for v in (e.scored.measured for e in problem.experiments))
    return float(n * np.log(best.fun / min(run.f[0], best.fun)))


def main(argv: list[str]) -> int:
    from rapid_cosim.compiler import build_models
    from rapid_cosim.diagnose.campaigns import SINGLE_SIZE
    from rapid_cosim.diagnose.catalogue import BASE_BENCH, EFFECTS
    from rapid_cosim.diagnose.study import FOREIGN, HIDDEN, draw_case, run_case
    from rapid_cosim.diagnose.workflow import DiagnoseOptions

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1-5")
    parser.add_argument("--effects", default=",".join([*HIDDEN, "doc_T4", "doc_T5", *VARIANTS, *FOREIGN, *PAIRS]))
    parser.add_argument("--event-effects", default=",".join(HIDDEN), help="effects hidden in event campaigns")
    parser.add_argument("--null-seeds", default="1-100", help="seeds of the effect-free campaigns")
    parser.add_argument("--n-jobs", type=int, default=2, help="cases in parallel")
    parser.add_argument("--max-effects", type=int, default=2)
    parser.add_argument("--keep", help="work folder to keep (default: a temporary one)")
    parser.add_argument("--report", metavar="WORK", help="print the results kept in WORK again, run nothing")
    parser.add_argument("--calibration", type=int, default=0, metavar="N",
                        help="also the true model on N effect-free staged campaigns (seeds 1000..): the adequacy "
                             "p-values' distribution, the family-wise false alarms and the intervals' coverage")
    parser.add_argument("--calibration-only", action="store_true", help="run only the calibration study")
    parser.add_argument("--json", type=Path, help="write the calibration study's figures there")
    args = parser.parse_args(argv)
    if args.report:
        with open(Path(args.report) / "results.pkl", "rb") as f:
            _print(*pickle.load(f))
        return 0

    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="rapid_cosim_study_"))
    package = work / "package" / "iGrGen"
    shutil.copytree(ROOT / "modelica" / "iGrGen", package, dirs_exist_ok=True)
    fmu_dir = work / "fmus"
    source = ModelSource(package, fmu_dir)
    build_models(list(dict.fromkeys([BASE_BENCH, *(e.bench for e in EFFECTS.values())])), package=package,
                 fmu_dir=fmu_dir, log=lambda *_: None)
    if args.calibration:
        calibration(args.calibration, work, package, fmu_dir, args.n_jobs, args.json)
        if args.calibration_only:
            return 0
    t0 = time.perf_counter()
    cases = [draw_case(t, s, source=source)
             for t in args.effects.split(",") if t for s in _seeds(args.seeds)]
    cases += [draw_case(t, s, source=source, kind="event")
              for t in args.event_effects.split(",") if t for s in _seeds(args.seeds)]
    cases += [draw_case("none", s, source=source) for s in _seeds(args.null_seeds)]
    single = draw_case("deadband", 1, SINGLE_SIZE, source=source)
    options = DiagnoseOptions(write_model=False, max_effects=args.max_effects)

    def one(case, label):
        opts = replace(options, judge=_truth_labels(case.truth))
        try:
            result = run_case(case, work / label, options=opts, source=source)
            result.check = _reached_from_truth(result) if case.kind == "event" and case.truth == "rate_limit" \
                else None
        except Exception as e:  # one campaign's crash is a finding, not the end of the study
            import traceback

            return Crash(case, f"{type(e).__name__}: {e}", traceback.format_exc())
        return result

    print(f"{len(cases)} campaigns + 1 single-step-size campaign, {args.n_jobs} in parallel; work folder {work}")
    results = joblib.Parallel(n_jobs=args.n_jobs)(
        [*(joblib.delayed(one)(c, "cases") for c in cases), joblib.delayed(one)(single, "single")])
    *results, single_result = results
    elapsed = time.perf_counter() - t0
    with open(work / "results.pkl", "wb") as f:  # --report WORK prints them again
        pickle.dump((results, single_result, elapsed), f)
    _print(results, single_result, elapsed)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0


def calibration(n: int, work: Path, package: Path, fmu_dir: Path, n_jobs: int, json_file: Path | None) -> dict:
    """The true model (TG Type I, nothing hidden) on ``n`` effect-free staged campaigns,
    the last test held out, as a diagnosis fits and judges its base model
    (:mod:`rapid_cosim.diagnose.false_alarms`)."""
    import json

    from rapid_cosim.diagnose.campaigns import draw_case, write_campaign
    from rapid_cosim.diagnose.false_alarms import fit_truth, summary, summary_text, to_json
    from rapid_cosim.diagnose.workflow import DiagnoseOptions
    from rapid_cosim.experiment import load_experiment

    options = DiagnoseOptions(write_model=False)
    source = ModelSource(package, fmu_dir)

    def one(seed):
        case = draw_case("none", seed, source=source)
        folder = work / "calibration" / case.label
        experiments = [load_experiment(p) for p in write_campaign(case, folder / "data", source=source)]
        truth = {k: v for k, v in case.plant.items() if k in ("gov.R", "gov.Ts")}
        fit = fit_truth(case.label, experiments[:-1], experiments[-1:], truth, folder / "fit", options,
                        source)
        shutil.rmtree(folder, ignore_errors=True)
        return fit

    t0 = time.perf_counter()
    fits = joblib.Parallel(n_jobs=n_jobs)(joblib.delayed(one)(1000 + k) for k in range(n))
    s = summary(fits)
    print(summary_text("staged campaigns (the diagnosis study's plants and recorders, effect-free)", s))
    print(f"  {time.perf_counter() - t0:.0f} s")
    if json_file:
        json_file.parent.mkdir(parents=True, exist_ok=True)
        json_file.write_text(json.dumps({"summary": s, "draws": to_json(fits)}, indent=1, default=float) + "\n")
    return s


class Crash:
    """A campaign whose diagnosis raised: reported first, with its traceback."""

    def __init__(self, case, error: str, trace: str):
        self.case, self.error, self.trace = case, error, trace


def _print(results, single_result, elapsed) -> None:
    from rapid_cosim.diagnose.study import confusion_text

    crashed = [r for r in [*results, single_result] if isinstance(r, Crash)]
    results = [r for r in results if not isinstance(r, Crash)]
    print()
    if crashed:
        print(f"CRASHED: {len(crashed)} campaign(s); the rates below are over the campaigns that finished:")
        for c in crashed:
            print(f"  {c.case.label}: {c.error}\n{c.trace}")
    for kind in ("staged", "event"):
        subset = [r for r in results if r.case.kind == kind]
        if subset:
            print(f"{kind} campaigns:")
            print(confusion_text(subset))
            print()
    report(results, None if isinstance(single_result, Crash) else single_result)
    per_case = [r.seconds for r in results]
    print(f"time: {elapsed:.0f} s in all (drawing the cases included), {np.median(per_case):.0f} s per campaign "
          f"(median; staged {np.median([r.seconds for r in results if r.case.kind == 'staged']):.0f} s, events "
          f"{np.median([r.seconds for r in results if r.case.kind == 'event'] or [0]):.0f} s; one process each)")


def report(results, single_result) -> None:
    from rapid_cosim.diagnose.catalogue import CATALOGUE, VARIANTS as VARIANT_EFFECTS
    from rapid_cosim.diagnose.study import FOREIGN

    null = [r for r in results if r.case.truth == "none"]
    if null:
        ok = [r for r in null if r.outcome == "none" and r.diagnosis.adequate]
        print(f"effect-free: none and adequate {len(ok)}/{len(null)} ({len(ok) / len(null):.1%}); unexplained "
              f"{sum(r.diagnosis.effect == 'unexplained' for r in null)}; an effect named "
              f"{sum(r.outcome not in ('none', 'unexplained', 'ambiguous') for r in null)}; ambiguous "
              f"{sum(r.diagnosis.effect == 'ambiguous' for r in null)}")
        p = [r.diagnosis.adequacy.before.p for r in null]
        print(f"  base model's campaign p-value on effect-free campaigns: median {np.median(p):.2f}, under 0.05 in "
              f"{sum(v < 0.05 for v in p)} of {len(p)} (a calibrated null: about 5 %)")
    judged = [(r, a) for r in results if r.case.truth not in FOREIGN
              for label, a in r.diagnosis.adequacy.judged.items() if label in _labels(r.case.truth)]
    if judged:
        print(f"the true model judged adequate: {sum(a.adequate for _, a in judged)}/{len(judged)}"
              + "".join(f"\n  inadequate: {r.case.label} (p {a.p:.2g})" for r, a in judged if not a.adequate))
    foreign = [r for r in results if r.case.foreign]
    if foreign:
        print(f"outside the catalogue: unexplained {sum(r.correct for r in foreign)}/{len(foreign)}; a wrong name as "
              f"the whole story {sum(r.wrong_whole_story for r in foreign)}")
    for kind in ("staged", "event"):
        singles = [r for r in results if r.case.kind == kind and r.case.truth in CATALOGUE
                   and not CATALOGUE[r.case.truth].relative]
        if singles:
            print(f"single catalogue effects named right ({kind}): {sum(r.correct for r in singles)}/{len(singles)} "
                  f"({sum(r.correct for r in singles) / len(singles):.0%})")
    documented = [r for r in results if r.case.truth.startswith("doc_")]
    if documented:
        print(f"documented constant off by x2, named: {sum(r.correct for r in documented)}/{len(documented)}")
    variants = [r for r in results if r.case.truth in VARIANT_EFFECTS]
    if variants:
        print(f"variants of form: the variant or its parent named (or the variant among the stories) "
              f"{sum(r.correct for r in variants)}/{len(variants)}; documentation blamed without naming the variant "
              f"{sum(r.documentation_blamed for r in variants)}")
    pairs = [r for r in results if "+" in r.case.truth]
    if pairs:
        print(f"pairs, both named: {sum(r.correct for r in pairs)}/{len(pairs)}")
    uncertain = [r for r in results if r.diagnosis.searched.search.uncertain]
    print(f"campaigns whose verdict says the search was uncertain: {len(uncertain)}"
          + "".join(f"\n  {r.case.label}: {r.diagnosis.searched.search.warning}" for r in uncertain))
    checked = [r for r in results if getattr(r, "check", None) is not None]
    if checked:
        missed = [r for r in checked if r.check > 2.0]
        print(f"event rate-limit campaigns: the multistart reached the best point in {len(checked) - len(missed)}/"
              f"{len(checked)} (a local fit from the true parameters found better by more than 2 in BIC in "
              f"{len(missed)})")
    if single_result is not None:
        d = single_result.diagnosis.named
        print(f"single step size, deadband hidden: verdict {d.effect}"
              + (f" between {' and '.join(d.candidates)}" if d.effect == "ambiguous" else "")
              + (f"; next: {d.separating_test.words}" if d.separating_test else ""))
    for r in results:
        if not r.correct:
            print(f"  missed {r.case.label}: {r.diagnosis.named.verdict} {r.diagnosis.named.candidates} "
                  f"({r.diagnosis.named.reason[:160]})")


def _labels(truth: str) -> tuple[str, ...]:
    return _truth_labels(truth)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
