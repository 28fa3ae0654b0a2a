"""Confusion matrix of structure selection on synthetic campaigns (``make bench-structures``).

For each structure of iGrGen.Governors and TG Type I, ``--seeds`` plants drawn at random
(:mod:`rapid_cosim.diagnose.structure_study` describes them: invented units around the
models' defaults, GGOV1's held on its load limiter at the higher dispatch), the field
campaign's ten staged tests each with the field's noise level, tests 4 and 8 held out;
every structure calibrated on every campaign. Prints the matrix (rows: the generating
structure; columns: the verdict), how often the generating structure is named, ranked
first, and named once the proposed separating test is run, each miss with the ranking,
and the time.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import joblib

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str]) -> int:
    from rapid_cosim.compiler import build_models
    from rapid_cosim.diagnose.structure_study import BENCH, ESTIMATE, confusion_text, run_structure_case

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="campaigns per structure")
    parser.add_argument("--structures", default=",".join(ESTIMATE))
    parser.add_argument("--n-jobs", type=int, default=2, help="campaigns in parallel")
    parser.add_argument("--method", default="pf:10+nm", help="calibration method of every structure")
    parser.add_argument("--keep", help="work folder to keep (default: a temporary one)")
    args = parser.parse_args(argv)
    truths = [s for s in args.structures.split(",") if s]
    unknown = sorted(set(truths) - set(ESTIMATE))
    if unknown:
        parser.error(f"unknown structure(s) {', '.join(unknown)}; known: {', '.join(ESTIMATE)}")

    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="rapid_cosim_structures_"))
    package = work / "package" / "iGrGen"
    shutil.copytree(ROOT / "modelica" / "iGrGen", package, dirs_exist_ok=True)
    fmu_dir = work / "fmus"
    build_models(list(BENCH.values()), package=package, fmu_dir=fmu_dir, log=lambda *_: None)
    jobs = [(t, s) for t in truths for s in range(1, args.seeds + 1)]
    print(f"{len(jobs)} campaigns, {len(ESTIMATE)} structures fitted on each, {args.n_jobs} in parallel; "
          f"work folder {work}")
    t0 = time.perf_counter()
    cases = joblib.Parallel(n_jobs=args.n_jobs)(
        joblib.delayed(run_structure_case)(t, s, work / "cases", package=package, fmu_dir=fmu_dir,
                                            method=args.method) for t, s in jobs)
    elapsed = time.perf_counter() - t0
    print()
    print(confusion_text(cases))
    for c in cases:
        if c.named != c.truth:
            print(f"  {c.truth}-{c.seed}: {c.named} ({c.verdict.reason[:160]})")
            print("    " + ", ".join(f"{f.name} {f.delta:+.1f}" + (f" (held out {f.heldout_score:.1f})"
                                                                 if f.heldout_score is not None else "")
                                     for f in c.verdict.ranking))
            if c.followup is not None:
                print(f"    {c.verdict.separating_test['advice']}; with it: {c.followup.structure} "
                      f"({c.followup.reason[:120]})")
    print(f"time: {elapsed:.0f} s in all, {sorted(c.seconds for c in cases)[len(cases) // 2]:.0f} s per campaign "
          "(median, one process each)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
