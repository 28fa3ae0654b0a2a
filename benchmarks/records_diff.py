"""Records before and after a change, compared by what they do (issue 53's rule, issue 54's
decision): ``make bench-replay`` and ``make bench-fleet`` run at two commits, their
answers read side by side (``make records-diff``).

    python benchmarks/records_diff.py --rev cb03e04 [--work results/records-diff]   # runs both, then compares
    python benchmarks/records_diff.py --before BEFORE/results --after results          # compares runs made
    python benchmarks/records_diff.py --before benchmarks/baselines/7176f80 --after results --parts fleet,structures

With ``--rev``, that commit is checked out into the work folder (``git worktree``) and its
own two benches run there (this checkout's environment, its code on ``PYTHONPATH``), then
this checkout's into ``--work``; a bench whose ``study.json`` is there already is not run
again. ``benchmarks/baselines/`` keeps an earlier revision's answers (its README), so
that only this checkout's benches need to run.

For ``bench-replay`` (``bench-replay/study.json``): per unit, the record delivered before
and after; where the texts differ, both are taken from the ANDES runs each study cached
(the same event, closed loop) and their electrical power compared: the RMSE and the largest
difference over the recorder's noise level, per event. For ``bench-fleet``
(``bench-fleet/fleet/results/units/*.json``): per unit, the route, the explanation's
verdict and the recommended fit before and after; where the records differ, both played on
the unit's event by the unit's own bench (its plant's inputs, the record's values over its
structure's constants), compared the same way. For ``bench-structures`` (``--parts
structures``, its campaigns kept in ``bench-structures/work``): per campaign, the structure
named, recommended and exported before and after; where the exported .dyr texts differ, both
read back and played by their structures on every test of the campaign, compared the same
way (the worst test). Prints every difference, and a line per bench: how many units have
the same record, how many differ by under 0.1 of the noise (RMSE) and 0.5 at any sample,
and every route or verdict that changed.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
RMSE_BAR, PEAK_BAR = 0.1, 0.5  # of the recorder's noise level


def _apart(d: np.ndarray, sigma: float) -> tuple[float, float]:
    """A difference of two responses over the noise level: RMSE and largest."""
    return float(np.sqrt(np.mean(d ** 2)) / sigma), float(np.max(np.abs(d)) / sigma)


def _cached(work: Path, record: str, event) -> dict | None:
    from replay_study import on_generator_1

    record = on_generator_1(record)
    path = work / "andes" / f"{hashlib.sha256((record + repr(event)).encode()).hexdigest()[:16]}.npz"
    return dict(np.load(path)) if path.exists() else None


def replay_diff(before: Path, after: Path) -> list[str]:
    import replay_study as rs

    old = {r["unit"]: r for r in json.loads((before / "bench-replay" / "study.json").read_text())}
    new = {r["unit"]: r for r in json.loads((after / "bench-replay" / "study.json").read_text())}
    lines, same, close, far = [], 0, 0, []
    for unit, a in old.items():
        b = new.get(unit)
        if b is None:
            lines.append(f"  {unit}: not in the run after")
            continue
        if a["fit"] != b["fit"]:
            far.append(f"{unit}: {a['fit']} -> {b['fit']}")
        if a["dyr"] == b["dyr"]:
            same += 1
            continue
        events = _events(unit, after)
        worst = (0.0, 0.0)
        for name, (event, sigma) in events.items():
            x, y = _cached(before / "bench-replay", a["dyr"], event), _cached(after / "bench-replay", b["dyr"], event)
            if x is None or y is None:
                lines.append(f"  {unit} {name}: no cached ANDES run to compare")
                continue
            d = np.interp(x["t"], y["t"], y["pe"]) - x["pe"]
            worst = max(worst, _apart(d, sigma))
        ok = worst[0] < RMSE_BAR and worst[1] < PEAK_BAR
        close += ok
        (lines.append if ok else far.append)(f"{unit}: record differs, its response by {worst[0]:.3f} (RMSE) and "
                                             f"{worst[1]:.3f} (largest) noise levels in ANDES")
    lines.insert(0, f"bench-replay: {len(old)} units before; the same record on {same}, a response within "
                    f"{RMSE_BAR:g}/{PEAK_BAR:g} of the noise on {close} more; otherwise: {len(far)}"
                 + "".join(f"\n  {f}" for f in far))
    del rs
    return lines


def _events(unit: str, after: Path) -> dict:
    """A replayed unit's events and noise levels, as replay_study judged them (a fleet
    unit's folder from the run ``after``)."""
    import replay_study as rs

    if unit.startswith("steam unit"):
        steam = rs.steam_generator()
        configs = [ROOT / "experiments" / "steam" / e for e in steam.EVENTS]
        sigmas = rs.noise_levels(configs)
        return {e: (ev, sigmas[e]) for e, (ev, _) in steam.EVENTS.items()}
    if unit.startswith("deadband unit") or unit.startswith("gas unit"):
        events, sigmas = rs.deadband_events() if unit.startswith("deadband") else rs.gas_events()
        return {e: (ev, sigmas[e]) for e, ev in events.items()}
    if unit.startswith("electrical unit"):
        sys.path.insert(0, str(ROOT / "experiments" / "electrical"))
        import andes_grid

        events = {"tgtypei_on": andes_grid.GridEvent(load=+1), "tgtypei_off_same": andes_grid.GridEvent(load=-1)}
        sigmas = rs.noise_levels([ROOT / "experiments" / "electrical" / e for e in events])
        return {e: (ev, sigmas[e]) for e, ev in events.items()}
    import andes_grid
    from rapid_cosim.fleet.synthetic import PRE_EVENT_S

    home = after / "bench-replay" / "fleet" / "units" / unit.split(" ")[0]
    event = andes_grid.GridEvent(load=+1, t_event=PRE_EVENT_S, duration=60.0 - 10.0 + PRE_EVENT_S)
    return {"event": (event, rs._unit_sigma(home))}


def fleet_diff(before: Path, after: Path) -> list[str]:
    from rapid_cosim.fleet.result import UnitResult

    def units(root: Path) -> dict:
        return {p.stem: UnitResult.from_json(json.loads(p.read_text()))
                for p in sorted((root / "bench-fleet" / "fleet" / "results" / "units").glob("*.json"))}

    old, new = units(before), units(after)
    lines, changed, same, close, far = [], [], 0, 0, []
    for name, a in old.items():
        b = new.get(name)
        if b is None:
            lines.append(f"  {name}: not in the run after")
            continue
        if (a.route, a.explanation) != (b.route, b.explanation):
            changed.append(f"{name}: {a.route.value} ({a.explanation or '-'}) -> {b.route.value} ({b.explanation or '-'})")
        ra, rb = a.recommended, b.recommended
        if ra is None or rb is None:
            same += ra is None and rb is None
            continue
        if ra.fit != rb.fit:
            changed.append(f"{name}: recommended {ra.fit} -> {rb.fit}")
        if ra.parameters == rb.parameters:
            same += 1
            continue
        rmse, peak = _played_apart(after / "bench-fleet" / "fleet" / "units" / name, ra, rb)
        ok = rmse < RMSE_BAR and peak < PEAK_BAR
        close += ok
        if not ok:
            far.append(f"{name}: {rb.fit}'s response moved by {rmse:.3f} (RMSE) and {peak:.3f} (largest) noise levels")
    lines.insert(0, f"bench-fleet: {len(old)} units before; routes or verdicts changed: {len(changed)}"
                 + "".join(f"\n  {c}" for c in changed)
                 + f"\n  records: the same on {same}, a response within {RMSE_BAR:g}/{PEAK_BAR:g} of the noise on "
                   f"{close} more; otherwise: {len(far)}" + "".join(f"\n  {f}" for f in far))
    return lines


def _played_apart(home: Path, a, b) -> tuple[float, float]:
    """Two records of a fleet unit played on its event by its bench: their difference over
    the unit's noise level (RMSE, largest)."""
    from rapid_cosim.compiler.source import ModelSource
    from rapid_cosim.diagnose.selection import noise_floors
    from rapid_cosim.exchange import model_named
    from rapid_cosim.experiment import load_experiment
    from rapid_cosim.fitting.objective import simulate_experiment
    from rapid_cosim.identify import Unit
    from rapid_cosim.noise import campaign_noise
    from rapid_cosim.structures.structure import Structure, on_structure

    unit = Unit.load(home)
    exp = load_experiment(unit.configs[0])
    fits = campaign_noise([exp])
    sigma = float(noise_floors([exp], fits)[exp.name].sigma)
    structure = next(Structure.load(p) for p in unit.structures if Structure.load(p).name == b.model)
    on = on_structure(structure, [exp], fits)[0]
    fmu = ModelSource(fmu_dir=ROOT / "fmus").fmu(on.model)
    table = model_named(b.model)
    curves = [simulate_experiment(on, fmu, table.played(r.parameters, {**on.fixed})) for r in (a, b)]
    out = [n for n in on.outputs if on.weights[n] > 0][0]
    d = curves[1][out] - curves[0][out]
    return _apart(d, sigma)


def structures_diff(before: Path, after: Path) -> list[str]:
    old = {(c["truth"], c["seed"]): c for c in json.loads((before / "bench-structures" / "study.json").read_text())}
    new = {(c["truth"], c["seed"]): c for c in json.loads((after / "bench-structures" / "study.json").read_text())}
    changed, same, close, far, nearest = [], 0, 0, [], []
    for key, a in old.items():
        b, name = new.get(key), "{}-{}".format(*key)
        if b is None:
            changed.append(f"{name}: not in the run after")
            continue
        if (a["named"], a["recommended"], a["exported"]) != (b["named"], b["recommended"], b["exported"]):
            changed.append(f"{name}: named {a['named']}, recommended {a['recommended']}, exported {a['exported']} -> "
                           f"{b['named']}, {b['recommended']}, {b['exported']}")
        records = [_structures_record(root, name, c) for root, c in ((before, a), (after, b))]
        if records[0][1].read_text() == records[1][1].read_text():
            same += 1
            continue
        rmse, peak = _campaign_apart(after / "bench-structures" / "work" / "cases" / name, *records)
        ok = rmse < RMSE_BAR and peak < PEAK_BAR
        close += ok
        nearest.append(f"{name}: {rmse:.3f} / {peak:.3f}")
        if not ok:
            far.append(f"{name}: {b['exported']}'s response moved by {rmse:.3f} (RMSE) and {peak:.3f} (largest) "
                       f"noise levels (worst test; RMSE/noise against the data {a['worst_rmse_over_noise']:.3f} -> "
                       f"{b['worst_rmse_over_noise']:.3f})")
    return [f"bench-structures: {len(old)} campaigns before; named, recommended or exported changed: {len(changed)}"
            + "".join(f"\n  {c}" for c in changed)
            + f"\n  exported records: the same on {same}, a response within {RMSE_BAR:g}/{PEAK_BAR:g} of the noise "
              f"on {close} more; otherwise: {len(far)}" + "".join(f"\n  {f}" for f in far)
            + ("\n  records that differ, their responses apart (RMSE / largest, noise levels): " + "; ".join(nearest)
               if nearest else "")]


def _structures_record(root: Path, name: str, case: dict) -> tuple[str, Path]:
    """A campaign's exported record: its structure and its .dyr file."""
    from rapid_cosim.identify.study import base_name

    model = base_name(case["exported"])
    return model, root / "bench-structures" / "work" / "cases" / name / f"{model}.dyr"


def _campaign_apart(folder: Path, a: tuple[str, Path], b: tuple[str, Path]) -> tuple[float, float]:
    """Two exported records of a bench-structures campaign, each played by its structure on
    every test of the campaign: their difference over each test's noise level (the worst
    test's RMSE, the largest at any sample)."""
    from rapid_cosim.compiler.source import ModelSource
    from rapid_cosim.diagnose.selection import noise_floors
    from rapid_cosim.exchange import read_record
    from rapid_cosim.experiment import load_experiment
    from rapid_cosim.fitting.objective import simulate_experiment
    from rapid_cosim.noise import campaign_noise
    from rapid_cosim.structures.structure import Structure, on_structure

    tests = [load_experiment(c) for c in sorted(folder.glob("test*/config.toml"))]
    fits = campaign_noise(tests)
    floors = noise_floors(tests, fits)
    source, curves = ModelSource(fmu_dir=ROOT / "fmus"), []
    for model, dyr in (a, b):
        record = read_record(dyr).values
        as_read, values = Structure.load(ROOT / "experiments" / "structures" / f"{model}.toml").playing(record)
        played = []
        for on in on_structure(as_read, tests, fits):
            out = [n for n in on.outputs if on.weights[n] > 0][0]
            played.append(simulate_experiment(on, source.fmu(on.model), {**on.fixed, **values})[out])
        curves.append(played)
    worst = (0.0, 0.0)
    for test, x, y in zip(tests, *curves):
        d, sigma = y - x, float(floors[test.name].sigma)
        worst = max(worst, _apart(d, sigma))
    return worst


BENCHES = {"replay": ("bench-replay", "bench-replay/study.json"), "fleet": ("bench-fleet", "bench-fleet/study.json"),
           "structures": ("bench-structures", "bench-structures/study.json")}


def run_benches(tree: Path, results: Path, parts: list[str]) -> None:
    """The two benches of ``tree``'s Makefile, with this checkout's environment, into
    ``results`` (each skipped where its study.json is there)."""
    import subprocess

    from identify_bench import tree_env

    venv = ROOT / ".venv"
    for part in parts:
        target, done = BENCHES[part]
        if (results / done).exists():
            continue
        print(f"  {tree.name}: make {target} ...", file=sys.stderr, flush=True)
        if part == "structures":  # its campaigns kept, to play both records on their tests
            subprocess.run([str(venv / "bin" / "python"), "benchmarks/structures_study.py", "--seeds", "10",
                            "--n-jobs", "2", "--keep", str(results / "bench-structures" / "work"), "--json",
                            str(results / done)], env=tree_env(tree), cwd=tree, check=True)
            continue
        # -o: this checkout's venv is not reinstalled from the tree's pyproject.toml
        subprocess.run(["make", "--no-print-directory", "-C", str(tree), f"VENV={venv}", "-o",
                        str(venv / ".installed"), f"RESULTS={results}", target], env=tree_env(tree), check=True)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rev", help="run the benches at this commit and here, then compare")
    parser.add_argument("--work", type=Path, default=ROOT / "results" / "records-diff")
    parser.add_argument("--before", type=Path, help="the earlier commit's results folder (runs made)")
    parser.add_argument("--after", type=Path, default=ROOT / "results")
    parser.add_argument("--parts", default="replay,fleet")
    args = parser.parse_args(argv)
    parts = args.parts.split(",")
    args.work = args.work.resolve()  # make -C and the study scripts run in the tree
    if args.rev:
        from identify_bench import checkout

        tree = checkout(args.rev, args.work)
        args.before, args.after = args.work / f"results-{args.rev}", args.work / "results-here"
        run_benches(tree, args.before, parts)
        run_benches(ROOT, args.after, parts)
    elif args.before is None:
        parser.error("give --rev, or --before with the earlier commit's results")
    if "replay" in parts:
        print("\n".join(replay_diff(args.before, args.after)))
    if "fleet" in parts:
        print("\n".join(fleet_diff(args.before, args.after)))
    if "structures" in parts:
        print("\n".join(structures_diff(args.before, args.after)))


if __name__ == "__main__":
    main()
