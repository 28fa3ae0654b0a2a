"""What fewer multistart starts would change (issue 42), read from a finished fleet's
archives alone, without simulating again.

Issue 42 asks for a one-event fleet unit in 5 s on one worker and for unchanged answers.
A unit runs about 27 fits (the explanation's candidates, the standard records), so 5 s is
about one Levenberg-Marquardt start per fit at today's cost of a simulation. Each fit's
archive keeps its waterfall: every start's final fitness, in the order the starts were
run (a nested model's own starts first, then the screened design's best points, best
first). So for each fit this asks: had only its first ``k`` starts run, would the best of
them be its best (within the multistart's margin, 1e-4 relative)? And, for each unit,
whether the fit that missed is the one its answer rests on: the recommended record's, or
the candidate its explanation names.

An estimate, on the generous side for fewer starts in one way and not in another: a
start that merged into a later one is taken at that one's end point; and a fit whose
first round reached its best with too few starts ran more rounds, which a cut to ``k``
starts might also run.

    python benchmarks/starts_study.py [results/bench-fleet/fleet/results]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
KS = (1, 2, 3, 4, 6, 8, 12)
MARGIN = 1e-4  # MSOptions.margin


def waterfalls(results: Path) -> dict[Path, tuple[np.ndarray, int, int]]:
    """Each multistart archive's final fitness per start, in the order they were run,
    with the simulations of its screen (the design scored before the starts) and of the
    whole fit."""
    from rapid_cosim.archive.reader import RunArchive

    out = {}
    for f in sorted(results.rglob("*.h5")):
        try:
            with RunArchive(f) as a:
                iterations = a.iterations()
        except Exception:  # noqa: BLE001 - not a run archive (a report's cache)
            continue
        steps = [it for it in iterations if it.extras and "start_fun" in it.extras]
        # an iteration's n_sims counts the run's simulations so far
        screen = max((it.n_sims for it in iterations if it.extras and "screen" in it.extras), default=0)
        if steps:
            out[f.relative_to(results)] = (np.asarray(steps[-1].extras["start_fun"], dtype=float), screen,
                                           iterations[-1].n_sims)
    return out


def simulations(fall: tuple[np.ndarray, int, int], k: int) -> float:
    """The fit's simulations had it run ``k`` starts: its screen, and its starts' share of
    the rest (the starts run in lockstep, so each takes about as many)."""
    fun, screen, total = fall
    return screen + (total - screen) * min(k, fun.size) / fun.size


def first_k_best(fun: np.ndarray, k: int) -> bool:
    """Whether the first ``k`` starts reach the best of all of them."""
    ok = np.isfinite(fun)
    if not ok.any() or k >= fun.size:
        return True
    best = fun[ok].min()
    head = fun[:k][np.isfinite(fun[:k])]
    return bool(head.size) and head.min() <= best + MARGIN * abs(best)


def answers(results: Path) -> dict[str, tuple[str, str]]:
    """Per identified unit: its recommended record and its explanation's named effect."""
    out = {}
    with open(results / "fleet.csv", newline="") as f:
        for row in csv.DictReader(f):
            if not row["recommended"]:
                continue
            diagnosis = results / "units" / row["unit"] / "explanation" / "diagnosis.json"
            effect = json.loads(diagnosis.read_text()).get("effect", "") if diagnosis.exists() else ""
            out[row["unit"]] = (row["recommended"], effect)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", nargs="?", default="results/bench-fleet/fleet/results",
                        help="a fleet's results folder (make bench-fleet's, or rapid-cosim fleet's)")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    warnings.simplefilter("ignore")
    results = Path(args.results)
    if not (results / "fleet.csv").exists():
        raise SystemExit(f"{results}: no fleet.csv; run make bench-fleet first, or name a fleet's results folder")
    falls = waterfalls(results)
    units = answers(results)
    starts = Counter(fall[0].size for fall in falls.values())
    total = sum(fall[2] for fall in falls.values())
    print(f"{len(falls)} multistart fits in {results} ({len(units)} units identified), {total:,} simulations; "
          f"starts per fit: median {int(np.median([f[0].size for f in falls.values()]))}, "
          f"{min(starts)} to {max(starts)}")
    print("first k starts | simulations (estimated) | fits at their best | units whose recommended record's fit "
          "is not | units whose named effect's fit is not")
    for k in KS:
        missed = [p for p, fall in falls.items() if not first_k_best(fall[0], k)]
        sims = sum(simulations(fall, k) for fall in falls.values())
        record = sorted({p.parts[1] for p in missed if p.parts[0] == "units" and p.parts[1] in units
                         and p.parts[2:] == ("records", f"{units[p.parts[1]][0]}.h5")})
        effect = sorted({p.parts[1] for p in missed if p.parts[0] == "units" and p.parts[1] in units
                         and p.parts[2:] == ("explanation", "candidates", f"{units[p.parts[1]][1]}.h5")})
        print(f"{k:14d} | {sims / total:5.0%} | {len(falls) - len(missed):5d} of {len(falls)} ({100 * (1 - len(missed) / len(falls)):.1f} %) | "
              f"{len(record):2d} {' '.join(record[:6])}{' ...' if len(record) > 6 else ''} | "
              f"{len(effect):2d} {' '.join(effect[:6])}{' ...' if len(effect) > 6 else ''}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
