"""The main jobs' stories and numbers before and after a change, in one run (issue 43's
"no change in behaviour"): ``make stories-diff``.

    python benchmarks/stories_diff.py [--before REV] [--after REV] [--targets demo,diagnose,identify,fleet]

Both revisions are checked out into the work folder (``git worktree``) and each runs the
repository's own ``make`` targets there, with this checkout's virtual environment and
its code on ``PYTHONPATH``, one revision after the other. What each target prints and
the files it writes that hold answers (the verdict JSON, the identification and its
``unit.dyr``, the fleet's JSON and records) are compared after removing what differs
from run to run by nature: wall times, the work folder's paths, dates and digests of
the code. Printed: per target, "same" or the differing lines as a unified diff. What a revision
printed is kept in its results folder (``printed.json``), so a second run with the same
revisions only compares. Exit status 1 when any part differs (``make stories-diff``
carries on: against b2983af some parts differ by design, docs/studies.md says which).
"""

from __future__ import annotations

import argparse
import difflib
import json
import re
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from identify_bench import BEFORE, ROOT, checkout, tree_env  # noqa: E402

TARGETS = ("demo", "diagnose", "identify", "fleet")
# the files of each target that hold its answers (relative to its results folder)
ANSWERS = {
    "demo": (),
    "diagnose": ("diagnose/verdict.json",),
    "identify": ("identify/identification.json", "identify/unit.dyr"),
    "fleet": ("fleet/fleet.json", "fleet/fleet.dyr", "fleet/fleet.csv"),
}
VOLATILE_KEYS = {"seconds", "wall", "wall_time", "created", "started", "finished_at", "elapsed", "digest",
                 "code_digest", "version", "git", "host", "python", "timestamp", "time_s"}


def run_targets(tree: Path, targets: list[str], results: Path) -> dict[str, str]:
    """Each target's printed output under ``tree``'s code and Makefile."""
    venv = ROOT / ".venv"
    env = tree_env(tree)
    out = {}
    for target in targets:
        # -o: this checkout's venv is not reinstalled from the tree's pyproject.toml
        done = subprocess.run(["make", "--no-print-directory", "-C", str(tree), f"VENV={venv}",
                               "-o", str(venv / ".installed"), f"RESULTS={results}", target],
                              env=env, capture_output=True, text=True)
        out[target] = done.stdout + done.stderr + f"\n(exit status {done.returncode})\n"
        print(f"  {tree.name}: make {target} -> exit {done.returncode}", file=sys.stderr)
    return out


def normalised(text: str, tree: Path, results: Path) -> list[str]:
    """``text`` without what differs from run to run by nature."""
    text = text.replace(str(results), "<results>").replace(str(tree), "<tree>")
    text = re.sub(r"\d+(\.\d+)? s wall time", "<t> s wall time", text)
    text = re.sub(r"\((\d+(\.\d+)?) s, ", "(<t> s, ", text)  # the fleet's summary line
    text = re.sub(r"\((\d+(\.\d+)?) s\)$", "(<t> s)", text, flags=re.M)  # demo's time per test
    text = re.sub(r"date \+%s\) - \d+", "date +%s) - <t0>", text)  # a Makefile recipe's start time
    text = re.sub(r"\bin \d+(\.\d+)? s\b", "in <t> s", text)  # a stage's time (data in seconds stay compared)
    text = re.sub(r"\d{4}-\d\d-\d\d[T ]\d\d:\d\d(:\d\d(\.\d+)?)?(Z|[+-]\d\d:?\d\d)?", "<date>", text)
    text = re.sub(r"\b(?=[0-9a-f]*[a-f])[0-9a-f]{12,64}\b", "<digest>", text)  # not a number's digits
    text = re.sub(r"^(test\d+\s+\S+\+\S+\s.*\s)\d+(\.\d+)?$", r"\1<t>", text, flags=re.M)  # demo's time column
    lines = [ln.rstrip() for ln in text.splitlines()]
    return [ln for ln in lines if ln and "it/s" not in ln and "s/it" not in ln and "%|" not in ln]


def answer_file(path: Path, tree: Path, results: Path) -> list[str]:
    if not path.exists():
        return ["<missing>"]
    if path.suffix == ".csv":
        import csv
        import io

        rows = list(csv.reader(io.StringIO(path.read_text())))
        timed = [k for k, name in enumerate(rows[0]) if name in VOLATILE_KEYS] if rows else []
        rows = [[("<t>" if k in timed and r is not rows[0] else v) for k, v in enumerate(r)] for r in rows]
        out = io.StringIO()
        csv.writer(out, lineterminator="\n").writerows(rows)
        text = out.getvalue()
    elif path.suffix == ".json":
        def strip(x):
            if isinstance(x, dict):
                return {k: strip(v) for k, v in x.items() if k not in VOLATILE_KEYS}
            if isinstance(x, list):
                return [strip(v) for v in x]
            return x
        text = json.dumps(strip(json.loads(path.read_text())), indent=1, sort_keys=True, default=str)
    else:
        text = path.read_text()
    return normalised(text, tree, results)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", default=BEFORE, help=f"revision before (default {BEFORE})")
    parser.add_argument("--after", default="HEAD", help="revision after (default HEAD)")
    parser.add_argument("--targets", default=",".join(TARGETS), help="make targets, comma-separated")
    parser.add_argument("--work", type=Path, default=Path("/tmp/stories-diff"), help="work folder")
    args = parser.parse_args(argv)
    targets = args.targets.split(",")
    args.work = args.work.resolve()  # the targets run in the revision's tree: a relative folder would land there
    args.work.mkdir(parents=True, exist_ok=True)
    revs = [subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", r], capture_output=True, text=True,
                           check=True).stdout.strip() for r in (args.before, args.after)]
    side = {}
    for rev in revs:
        tree = checkout(rev, args.work)
        results = args.work / f"results-{rev}"
        results.mkdir(parents=True, exist_ok=True)
        kept = results / "printed.json"  # a revision's run kept: a run stopped half-way goes on
        printed = json.loads(kept.read_text()) if kept.exists() else {}
        if set(targets) - set(printed):
            printed.update(run_targets(tree, [t for t in targets if t not in printed], results))
            kept.write_text(json.dumps(printed))
        else:
            print(f"  kept {kept} (remove it to run {rev} again)", file=sys.stderr)
        side[rev] = {t: (normalised(printed[t], tree, results),
                         {f: answer_file(results / f, tree, results) for f in ANSWERS.get(t, ())}) for t in targets}
    before, after = (side[r] for r in revs)
    differing = 0
    print(f"make {' '.join(targets)}: {revs[0]} (before) against {revs[1]} (after)")
    for t in targets:
        parts = [("printed", before[t][0], after[t][0])]
        parts += [(f, before[t][1][f], after[t][1][f]) for f in before[t][1]]
        for what, a, b in parts:
            if a == b:
                print(f"  {t:9s} {what}: same ({len(a)} lines)")
                continue
            differing += 1
            diff = list(difflib.unified_diff(a, b, f"{revs[0]}/{what}", f"{revs[1]}/{what}", lineterm="", n=1))
            print(f"  {t:9s} {what}: {sum(1 for d in diff if d[:1] in '+-') - 2} lines differ")
            print("\n".join("      " + d for d in diff[:200]))
            if len(diff) > 200:
                print(f"      ... {len(diff) - 200} more diff lines not shown")
    print(f"{differing} part(s) differ")
    return 1 if differing else 0


if __name__ == "__main__":
    raise SystemExit(main())
