"""What fewer multistart starts would change (issue 42), read from a finished fleet's
archives, simulating only what the standard errors need.

Issue 42 asks for a one-event fleet unit in 5 s on one worker and for unchanged answers.
A unit runs about 27 fits (the explanation's candidates, the standard records), so 5 s is
about one Levenberg-Marquardt start per fit at today's cost of a simulation. Each fit's
archive keeps its waterfall: every start's end point and final fitness, in the order the
starts were run (a nested model's optimum and its own small design first, then the
screened design's best points, best first). So for each fit this asks: had only its
first ``k`` starts run, would the best of them be its best (within the multistart's
margin, 1e-4 relative)? Then, for each identified unit, whether the fit that missed is
one its answer rests on (the recommended record's, or the candidate its explanation's
verdict names: an effect, or none), and how far the recommended record's estimate would move: the largest move of
one parameter in its standard error (the Fisher information at the fit's best point, as
``rapid-cosim identify`` reports it), which issue 42 wants under 0.1.

An estimate, in both directions: a start that merged into a later one is taken at that
one's end point; a fit whose first starts reached its best too few times ran more rounds,
which a cut to ``k`` starts might run too; and a rival's fit that misses its best can
change which record is recommended, which this does not count. The simulations are
estimated as each fit's screen and its starts' equal shares of the rest.

    python benchmarks/starts_study.py [results/bench-fleet/fleet/results]
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
KS = (1, 2, 3, 4, 6, 8, 12)
MARGIN = 1e-4  # MSOptions.margin


@dataclass
class Waterfall:
    """One multistart fit as its archive keeps it."""

    fun: np.ndarray  # each start's final fitness, in run order
    u: np.ndarray  # each start's end point, unit coordinates
    x: np.ndarray  # the fit's best point
    screen: int  # simulations of the design scored before the starts
    total: int  # simulations of the whole fit

    def first_k_best(self, k: int) -> int | None:
        """The start the first ``k`` end at (their best), or None where that is the fit's best."""
        ok = np.isfinite(self.fun)
        if not ok.any() or k >= self.fun.size:
            return None
        best = self.fun[ok].min()
        head = np.where(np.isfinite(self.fun[:k]), self.fun[:k], np.inf)
        i = int(np.argmin(head))
        return None if head[i] <= best + MARGIN * abs(best) else i

    def simulations(self, k: int) -> float:
        return self.screen + (self.total - self.screen) * min(k, self.fun.size) / self.fun.size


def waterfalls(results: Path) -> tuple[dict[Path, Waterfall], int, int]:
    """Every finished multistart archive under ``results`` (by path relative to it), and
    the numbers of archives that could not be read and of runs that did not finish."""
    from rapid_cosim.archive.reader import RunArchive
    from rapid_cosim.errors import ArchiveError

    out, unreadable, unfinished = {}, 0, 0
    for f in sorted(results.rglob("*.h5")):
        try:
            with RunArchive(f) as a:
                iterations, result = a.iterations(), a.result()
        except ArchiveError:
            if f.name != "diagnosis.h5":  # a diagnosis record, not a run
                unreadable += 1
            continue
        steps = [it for it in iterations if it.extras and "start_fun" in it.extras]
        if not steps:
            continue
        if result is None:
            unfinished += 1
            continue
        # an iteration's n_sims counts the run's simulations so far
        screen = max((it.n_sims for it in iterations if it.extras and "screen" in it.extras), default=0)
        extras = steps[-1].extras
        out[f.relative_to(results)] = Waterfall(np.asarray(extras["start_fun"], dtype=float),
                                                np.asarray(extras["start_u"], dtype=float),
                                                np.asarray(result.x, dtype=float), screen, iterations[-1].n_sims)
    return out, unreadable, unfinished


@dataclass
class Unit:
    folder: Path  # the unit's own files
    record: str  # the recommended record's fit
    effect: str | None  # the candidate archive its explanation's verdict rests on (an effect, or none)


def identified(results: Path) -> dict[str, Unit]:
    fleet = json.loads((results / "fleet.json").read_text())
    out = {}
    for u in fleet["units"]:
        if not u.get("recommended"):
            continue
        diagnosis = results / "units" / u["unit"] / "explanation" / "diagnosis.json"
        effect = None
        if diagnosis.exists():
            d = json.loads(diagnosis.read_text())
            # an ambiguous or unexplained verdict names no fit
            archive = d.get("archives", {}).get("+".join(d.get("effects") or []) or d.get("effect", ""))
            effect = Path(archive).name if archive else None
        out[u["unit"]] = Unit(Path(u["folder"]), u["recommended"]["fit"], effect)
    return out


@dataclass
class Errors:
    """A recommended record's standard errors at its best point, with its search space."""

    space: object  # the fit's SearchSpace
    x: np.ndarray  # the best point
    se: np.ndarray  # each parameter's standard error there (absolute)

    def move(self, u: np.ndarray) -> tuple[float, str]:
        """The largest move of one parameter, in its standard error, from the best point to
        ``u`` (unit coordinates), and that parameter's name."""
        x = self.space.from_unit(np.clip(u, 0.0, 1.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            moves = np.where(self.se > 0, np.abs(x - self.x) / self.se, np.where(x == self.x, 0.0, np.inf))
        k = int(np.argmax(moves))
        return float(moves[k]), self.space.names[k]


def standard_errors(unit: Unit, fall: Waterfall) -> Errors:
    """The record's standard errors at its best point, from the Fisher information as
    ``rapid-cosim identify`` reports it: the unit's tests, noise and structure as the fleet
    identified them."""
    from rapid_cosim.calibration import inputs_from_experiments
    from rapid_cosim.diagnose.selection import noise_floors
    from rapid_cosim.diagnose.workflow import split_holdout
    from rapid_cosim.identify.check import check_unit
    from rapid_cosim.identify.workflow import delivery_candidates
    from rapid_cosim.noise import campaign_noise
    from rapid_cosim.structures.identifiability import identifiability
    from rapid_cosim.structures.structure import on_structure

    check = check_unit(unit.folder)
    if not check.ok:
        raise SystemExit(f"{unit.folder}: the unit's files no longer check out ({check.findings[0]}); the standard "
                         "errors need the unit the fleet identified")
    training, heldout = split_holdout(check.experiments, check.unit.holdout)
    fitted = campaign_noise([*training, *heldout])
    structure = next((s for s in delivery_candidates(check.structures) if s.name == unit.record), None)
    if structure is None:
        raise SystemExit(f"{unit.folder}: no structure {unit.record} in the unit's files")
    inputs = inputs_from_experiments(on_structure(structure, training, fitted))
    ident = identifiability(inputs, fall.x, noise_floors([*training, *heldout], fitted))
    # relative to the value, or absolute where the value is 0 (identifiability's scale)
    se = np.where(fall.x != 0, np.abs(fall.x), 1.0) * np.asarray(ident.relative_se)
    return Errors(inputs.problem.space, fall.x, se)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", nargs="?", default="results/bench-fleet/fleet/results",
                        help="a fleet's results folder (make bench-fleet's, or rapid-cosim fleet's)")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    warnings.simplefilter("ignore")
    results = Path(args.results)
    if not (results / "fleet.json").exists():
        raise SystemExit(f"{results}: no fleet.json; run make bench-fleet first, or name a fleet's results folder")
    falls, unreadable, unfinished = waterfalls(results)
    if not falls:
        raise SystemExit(f"{results}: no multistart archives")
    units = identified(results)
    named = sum(u.effect is not None for u in units.values())
    total = sum(f.total for f in falls.values())
    sizes = [f.fun.size for f in falls.values()]
    left = ", ".join(f"{n} {what}" for n, what in ((unreadable, "unreadable"), (unfinished, "unfinished")) if n)
    print(f"{len(falls)} multistart fits in {results}{f' ({left}: left out)' if left else ''}: "
          f"{total:,} simulations, {int(np.median(sizes))} starts a fit (median; {min(sizes)} to {max(sizes)}); "
          f"{len(units)} units identified, {named} of them with a verdict naming one fit (an effect, a pair, or none)")
    print(f"first k starts | the fits' simulations (estimated) | fits at their best | units whose recommended "
          f"record's fit is not (of {len(units)}): its estimate moves, in SE | units whose verdict's fit is not "
          f"(of {named})")
    errors: dict[str, Errors] = {}  # per unit: its record's errors are the same whichever start missed
    for k in KS:
        missed = {p: i for p, f in falls.items() if (i := f.first_k_best(k)) is not None}
        record, effect = [], []
        for p, i in missed.items():
            name = p.parts[1] if len(p.parts) > 2 and p.parts[0] == "units" else None
            if name not in units:
                continue
            if p.parts[2:] == ("records", f"{units[name].record}.h5"):
                if name not in errors:
                    errors[name] = standard_errors(units[name], falls[p])
                record.append((name, *errors[name].move(falls[p].u[i])))
            elif p.parts[2:] == ("explanation", "candidates", units[name].effect):
                effect.append(name)
        sims = sum(f.simulations(k) for f in falls.values()) / total
        moves = ", ".join(f"{n} {m:.2g} ({q.removeprefix('gov.')})" for n, m, q in sorted(record))
        over = sum(m > 0.1 for _, m, _ in record)
        print(f"{k:14d} | {sims:4.0%} | {len(falls) - len(missed)} ({1 - len(missed) / len(falls):.1%}) | "
              f"{len(record)}, {over} of them over 0.1 SE: {moves or '-'} | {len(effect)} {' '.join(sorted(effect))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
