"""Confusion matrix of the discrepancy workflow on synthetic campaigns (``make bench-diagnose``).

Every catalogue effect (and none) is hidden, at a realistic and visible size, in a
three-test campaign (-200 mHz, +100 mHz and +200 mHz steps, each returned; the last held
out) with white + AR(1) noise and a meter offset, for each seed; one more campaign has a
deadband and a single step size, where the right answer is "ambiguous". Cases run in
parallel processes (``--n-jobs``). Prints the matrix, the gap shrinkage and the time.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import joblib
import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _seeds(spec: str) -> list[int]:
    out = []
    for part in spec.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def main(argv: list[str]) -> int:
    from rapid_cosim.compiler import build_models
    from rapid_cosim.diagnose.catalogue import BASE_BENCH, CATALOGUE
    from rapid_cosim.diagnose.study import SINGLE_SIZE, confusion_text, draw_case, run_case
    from rapid_cosim.diagnose.workflow import DiagnoseOptions

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1-5")
    parser.add_argument("--effects", default=",".join([*CATALOGUE, "none"]))
    parser.add_argument("--n-jobs", type=int, default=2, help="cases in parallel")
    parser.add_argument("--max-effects", type=int, default=2)
    parser.add_argument("--keep", help="work folder to keep (default: a temporary one)")
    args = parser.parse_args(argv)

    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="rapid_cosim_study_"))
    package = work / "package" / "iGrGen"
    shutil.copytree(ROOT / "modelica" / "iGrGen", package, dirs_exist_ok=True)
    fmu_dir = work / "fmus"
    build_models([BASE_BENCH, *(e.bench for e in CATALOGUE.values())], package=package, fmu_dir=fmu_dir,
                 log=lambda *_: None)
    cases = [draw_case(t, s, package=package, fmu_dir=fmu_dir)
             for t in args.effects.split(",") for s in _seeds(args.seeds)]
    single = draw_case("deadband", 1, SINGLE_SIZE, package=package, fmu_dir=fmu_dir)
    options = DiagnoseOptions(write_model=False, max_effects=args.max_effects)

    def one(case, label):
        return run_case(case, work / label, options=options, package=package, fmu_dir=fmu_dir)

    print(f"{len(cases)} campaigns + 1 single-step-size campaign, {args.n_jobs} in parallel; work folder {work}")
    t0 = time.perf_counter()
    # the single-size case has the label of a regular deadband case: its own folder, or
    # run_case (which clears the case folder first) would wipe the other's work in parallel
    results = joblib.Parallel(n_jobs=args.n_jobs)(
        [*(joblib.delayed(one)(c, "cases") for c in cases), joblib.delayed(one)(single, "single")])
    *results, single_result = results
    elapsed = time.perf_counter() - t0
    print()
    print(confusion_text(results))
    null = [r for r in results if r.case.truth == "none"]
    if null:
        print(f"none returned for {sum(r.named_first == 'none' for r in null)}/{len(null)} null campaigns")
    d = single_result.diagnosis
    print(f"single step size, deadband hidden: verdict {d.effect}"
          + (f" between {' and '.join(d.candidates)}" if d.effect == "ambiguous" else "")
          + (f"; next: {d.separating_test['advice']}" if d.separating_test else ""))
    wrong = [r for r in results if not r.correct]
    for r in wrong:
        print(f"  missed {r.case.label}: {r.diagnosis.effect} {r.diagnosis.candidates} ({r.diagnosis.reason[:120]})")
    per_case = [r.seconds for r in results]
    print(f"time: {elapsed:.0f} s in all, {np.median(per_case):.0f} s per campaign (median, one process each)")
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
