"""An identification timed before and after the speed work, in one run (issue 42):
``make bench-identify``.

    python benchmarks/identify_bench.py [--before REV] [--units steam,electrical,field] [--fleet 10]

The code of revision ``--before`` (default: the last commit before issue 54's second speed
round; ``--before b2983af`` for issue 42's) and of
``--after`` (default: HEAD) are checked out into the work folder (``git worktree``; the
checkout's own files may change while it runs), and each unit is
identified by both, one after the other on this machine: the steam unit with a binding
opening rate and three events (``experiments/steam``), the electrical unit, the field
unit of ten staged tests (``experiments/unit.toml``), then ``--fleet`` synthetic units as
``rapid-cosim fleet`` runs them on 2 workers. Each unit is run by
``benchmarks/profile_identify.py`` (in one process with every stage timed, then on 2
workers as ``rapid-cosim identify`` runs), under each revision's code.

Printed side by side: the wall times (one process, 2 workers) and their ratios, each
stage's seconds and ratio, the simulations per unit and the share of the one-process
time spent simulating; and the answers (the explanation's verdict, the recommended
record and its fit, every estimate's move in its standard error, and issue 54's measure:
both records played on every test of the unit, their largest difference in noise units).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from rapid_cosim.compiler.source import ModelSource

ROOT = Path(__file__).resolve().parents[1]
BEFORE = "7176f80"  # the last commit before the second speed round (issue 54; issue 42's was b2983af)


def tree_env(tree: Path) -> dict:
    """The environment a revision's checkout runs in: its code, its FMUs."""
    return {**os.environ, "PYTHONPATH": str(tree), "RAPID_COSIM_FMUS": str(tree / "fmus")}


def checkout(rev: str, work: Path) -> Path:
    tree = work / f"tree-{rev}"
    if not tree.exists():
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), rev], check=True,
                       capture_output=True)
    return tree


def build(tree: Path) -> None:
    """The tree's FMUs built before anything is timed."""
    env = tree_env(tree)
    subprocess.run([sys.executable, "-m", "rapid_cosim.cli", "build"], env=env, cwd=tree, check=True,
                   stdout=subprocess.DEVNULL)


def run_profile(tree: Path, units: list[str], work: Path) -> dict:
    """profile_identify.py (this tree's) under ``tree``'s code; a profile already in the
    work folder is kept (its tree is named by its revision), so a run stopped half-way
    goes on where it stopped."""
    out = work / f"profile-{tree.name}.json"
    if out.exists():
        print(f"kept {out} (remove it to profile {tree.name} again)", file=sys.stderr)
        return json.loads(out.read_text())
    env = tree_env(tree)
    subprocess.run([sys.executable, str(ROOT / "benchmarks" / "profile_identify.py"), "--units", ",".join(units),
                    "--work", str(work / f"runs-{tree.name}"), "--json", str(out)], env=env, check=True,
                   cwd=tree, stdout=subprocess.DEVNULL)
    return json.loads(out.read_text())


def run_fleet(tree: Path, fleet: Path, work: Path) -> dict:
    """The synthetic fleet on 2 workers under ``tree``'s code: the wall time, each unit's
    seconds, path and recommended record."""
    code = ("import json, sys, time\nimport rapid_cosim as rc\nt0 = time.perf_counter()\n"
            f"r = rc.fleet({str(fleet)!r}, results={str(work / ('fleet-' + tree.name))!r}, "  # 2 workers, the default
            "progress=False, log=lambda *_: None)\n"
            "rows = [u.to_json() if hasattr(u, 'to_json') else u for u in r.units]\n"
            "print(json.dumps({'wall': time.perf_counter() - t0, 'units': [{'unit': u['unit'], 'route': "
            "u.get('route', u.get('path')), 'seconds': u['seconds'], 'recommended': u.get('recommended')} "
            "for u in rows]}, default=str))\n")
    env = tree_env(tree)
    done = subprocess.run([sys.executable, "-c", code], env=env, cwd=tree, check=True, capture_output=True,
                          text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def behaviour(unit: str, before: dict, after: dict) -> str:
    """Issue 54's rule: the recommended records of both runs played on every test of the
    unit by its own bench (each fit's structure, its optional parts as freed), their largest
    difference over the test's recorder noise level (RMSE, and at any sample)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from profile_identify import UNITS
    from rapid_cosim.diagnose.selection import noise_floors
    from rapid_cosim.fitting.objective import simulate_experiment
    from rapid_cosim.identify.check import check_unit
    from rapid_cosim.identify.workflow import delivery_candidates
    from rapid_cosim.noise import campaign_noise
    from rapid_cosim.structures.structure import on_structure

    if not before["fit"] or not after["fit"]:
        return "no record to play" if before["fit"] == after["fit"] else "a record on one side only"
    source = ModelSource(fmu_dir=ROOT / "fmus")
    check = check_unit(UNITS[unit], source=source)
    fits = campaign_noise(check.experiments)
    floors = noise_floors(check.experiments, fits)
    candidates = {s.name: s for s in delivery_candidates(check.structures)}
    worst = (0.0, 0.0, "-")
    for exp in check.experiments:
        curves = []
        for ans in (before, after):
            on = on_structure(candidates[ans["fit"]], [exp], fits)[0]
            curves.append(simulate_experiment(on, source.fmu(on.model), {**on.fixed, **ans["parameters"]}))
        out = [n for n in on.outputs if on.weights[n] > 0][0]
        d = (curves[1][out] - curves[0][out]) / float(floors[exp.name].sigma)
        worst = max(worst, (float(np.sqrt(np.mean(d ** 2))), float(np.max(np.abs(d))), exp.name))
    return f"largest behaviour difference {worst[0]:.3f} (RMSE) and {worst[1]:.3f} (largest) noise levels ({worst[2]})"


def fleet_behaviour(home: Path, before: dict, after: dict) -> str:
    """A fleet unit's two recommended records played on its event (records_diff's way)."""
    from types import SimpleNamespace

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from records_diff import _played_apart

    if before["parameters"] == after["parameters"]:
        return "the same record"
    rmse, peak = _played_apart(home, *(SimpleNamespace(model=r["model"], parameters=r["parameters"])
                                       for r in (before, after)))
    return f"behaviour {rmse:.3f} (RMSE) and {peak:.3f} (largest) noise levels apart"


def moves(before: dict, after: dict) -> str:
    """Every estimate's move in its standard error (the larger of the two runs')."""
    out = []
    for name, b in before["parameters"].items():
        a = after["parameters"].get(name)
        se = max(before["se"].get(name, 0.0), after["se"].get(name, 0.0))
        if a is None:
            continue
        out.append((abs(a - b) / se if se > 0 else (0.0 if a == b else float("inf")), name))
    worst = max(out, default=(0.0, "-"))
    return f"largest estimate move {worst[0]:.3f} SE ({worst[1].removeprefix('gov.')})"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", default=BEFORE)
    parser.add_argument("--after", default="HEAD", help="the revision after (default the checkout's HEAD)")
    parser.add_argument("--units", default="steam,electrical,field")
    parser.add_argument("--fleet", type=int, default=10)
    parser.add_argument("--work", default="results/bench-identify")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    work = Path(args.work).resolve()
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    after = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", args.after], check=True,
                           capture_output=True, text=True).stdout.strip()
    trees = {"before": checkout(args.before, work), "after": checkout(after, work)}
    units = args.units.split(",")
    for tree in trees.values():
        build(tree)
    profiles = {k: run_profile(tree, units, work) for k, tree in trees.items()}
    fleets = {}
    if args.fleet:
        sys.path.insert(0, str(ROOT))
        from rapid_cosim.fleet.synthetic import make_fleet

        spec = work / "fleet" / "fleet.toml"
        if not spec.exists():
            make_fleet(work / "fleet", args.fleet, experiments=ROOT / "experiments", seed=1, source=ModelSource(fmu_dir=ROOT / "fmus"))
        fleets = {k: run_fleet(tree, spec, work) for k, tree in trees.items()}
    lines = []
    for name in units:
        b, a = profiles["before"][name], profiles["after"][name]
        lines.append(f"{name}: one process {b['one_process_s']:.1f} -> {a['one_process_s']:.1f} s "
                     f"(x{b['one_process_s'] / a['one_process_s']:.2f}); 2 workers {b['two_workers_s']:.1f} -> "
                     f"{a['two_workers_s']:.1f} s (x{b['two_workers_s'] / a['two_workers_s']:.2f}); simulations "
                     f"{b['simulations']:,} -> {a['simulations']:,}")
        for stage in sorted(set(b["stages"]) | set(a["stages"]), key=lambda s: -b["stages"].get(s, {}).get(
                "seconds", 0.0)):
            sb, sa = (x["stages"].get(stage, {}).get("seconds", 0.0) for x in (b, a))
            if max(sb, sa) >= 0.1:
                lines.append(f"  {stage:<30} {sb:7.2f} -> {sa:7.2f} s" + (f"  x{sb / sa:.2f}" if sa > 0 else ""))
        share = [sum(r.get("simulation", 0.0) for r in x["stages"].values()) / x["one_process_s"] for x in (b, a)]
        lines.append(f"  simulating: {100 * share[0]:.0f} % -> {100 * share[1]:.0f} % of the one-process time")
        ab, aa = b["answer"], a["answer"]
        same = (ab["explanation"], ab["recommended"], ab["fit"]) == (aa["explanation"], aa["recommended"], aa["fit"])
        lines.append(f"  answer: {aa['explanation']}; {aa['fit']} recommended; "
                     + ("the same verdict and record" if same else
                        f"CHANGED from {ab['explanation']}; {ab['fit']}") + f"; {moves(ab, aa)}")
        lines.append(f"  {behaviour(name, ab, aa)}")
    if fleets:
        b, a = fleets["before"], fleets["after"]
        lines.append(f"fleet of {len(a['units'])} units on 2 workers: {b['wall']:.0f} -> {a['wall']:.0f} s "
                     f"(x{b['wall'] / a['wall']:.2f})")
        for ub, ua in zip(b["units"], a["units"]):
            rb, ra = ub.get("recommended") or {}, ua.get("recommended") or {}
            same = (ub["route"], rb.get("fit")) == (ua["route"], ra.get("fit"))
            lines.append(f"  {ua['unit']}: {ub['seconds']:.0f} -> {ua['seconds']:.0f} s, {ua['route']}"
                         + (f", {ra.get('fit')}" if ra else "") + ("" if same else
                                                                    f" (before: {ub['route']}, {rb.get('fit')})")
                         + (f"; {fleet_behaviour(work / 'fleet' / 'units' / ua['unit'], rb, ra)}" if ra and rb else ""))
    lines.append(f"make bench-identify: {time.perf_counter() - t0:.0f} s")
    print("\n".join(lines))
    if args.json:
        Path(args.json).write_text(json.dumps({"profiles": profiles, "fleets": fleets}, indent=1) + "\n")


if __name__ == "__main__":
    main()
