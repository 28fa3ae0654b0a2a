"""Does the unit identification name the generating structure, and does the record it
exports reproduce the tests? (``make bench-structures``)

For each standard structure (TGOV1, IEEEG1, GGOV1, HYGOV), ``--seeds`` invented plants
(:mod:`rapid_cosim.identify.study` describes them; half the IEEEG1 ones with
binding valve rate limits), each put through the field's ten staged tests with realistic
recorder noise, tests 4 and 8 held out, and through identify's path: every structure,
IEEEG1 with its optional Uo/Uc and each with its optional deadband fitted by multistart
least squares with one fitted noise model, the records kept and recommended by identify's
rules, the winner exported as a .dyr, read back and simulated on every test. Prints one
line per campaign, then per structure how often it is named, recommended and first by
BIC, whether binding Uo/Uc were freed, how often a deadband was kept free (no plant has
one), the exported record's RMSE over the noise (worst test of each campaign: max and
median), each miss with its ranking, and the time.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import joblib

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str]) -> int:
    from rapid_cosim.compiler import build_models
    from rapid_cosim.compiler.source import ModelSource
    from rapid_cosim.identify.study import STANDARD, Structure, case_line, miss_lines, \
        run_structure_case, summary_text

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="campaigns per structure")
    parser.add_argument("--structures", default=",".join(STANDARD), help="generating structures")
    parser.add_argument("--n-jobs", type=int, default=2, help="campaigns in parallel")
    parser.add_argument("--keep", help="work folder to keep (default: a temporary one)")
    parser.add_argument("--json", help="write every campaign's outcome here")
    args = parser.parse_args(argv)
    truths = [s for s in args.structures.split(",") if s]
    unknown = sorted(set(truths) - set(STANDARD))
    if unknown:
        parser.error(f"unknown structure(s) {', '.join(unknown)}; known: {', '.join(STANDARD)}")

    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="rapid_cosim_structures_"))
    package, fmu_dir = ROOT / "modelica" / "iGrGen", ROOT / "fmus"
    structures_dir = ROOT / "experiments" / "structures"
    build_models([Structure.load(structures_dir / f"{s}.toml").bench for s in STANDARD], package=package,
                 fmu_dir=fmu_dir, log=lambda *_: None)
    jobs = [(t, s) for s in range(1, args.seeds + 1) for t in truths]  # every structure early in the log
    print(f"{len(jobs)} campaigns, {len(STANDARD)} structures, IEEEG1 with Uo/Uc and each with its deadband "
          "fitted on each, "
          f"{args.n_jobs} in parallel; work folder {work}", flush=True)
    t0 = time.perf_counter()
    cases = []
    for case in joblib.Parallel(n_jobs=args.n_jobs, return_as="generator")(
            joblib.delayed(run_structure_case)(t, s, work / "cases", source=ModelSource(package, fmu_dir),
                                              structures_dir=structures_dir)
            for t, s in jobs):
        cases.append(case)
        print(case_line(case), flush=True)
    elapsed = time.perf_counter() - t0
    print()
    print(summary_text(cases))
    misses = [c for c in cases if c.named != c.truth]
    if misses:
        print("campaigns whose generating structure was not named:")
        for c in misses:
            print("\n".join(miss_lines(c)))
    print(f"time: {elapsed:.0f} s in all, {sorted(c.seconds for c in cases)[len(cases) // 2]:.0f} s per campaign "
          "(median, one process each)")
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps([c.to_json() for c in cases], indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
