"""Recordings as recorders write them (issue 31): the committed ANDES events with nothing
changed but their time base.

    python benchmarks/timebase_study.py --work results/bench-timebase      # make bench-timebase
    python benchmarks/timebase_study.py --events tgov1_on --variants clean,jitter3  # a part

Each committed event of ``experiments/electrical`` (generate.py: ANDES 2.0's Kundur grid,
generator 1 with TGOV1, IEEEG1 or TG Type I, one with a hidden valve rate) is recorded
again at new stamps: ANDES's noise-free run (5 ms steps, ``generate.andes_run``, cached in
the work folder) read at each new stamp, plus the event's own noise draw, frame by frame
(``data.csv`` less ``clean.csv``: the same values in the same order). Any change in the
answer then comes from the time base alone. The variants (:data:`VARIANTS`; the random
ones seeded per event):

- ``clean``: the committed recording itself;
- ``jitter1``/``jitter3``/``jitter5``: every stamp moved uniformly within +-1, 3, 5 ms;
- ``drop0.1``/``drop1``: 0.1 % and 1 % of the frames dropped; ``burst5``: four bursts of
  five frames dropped;
- ``repeat1``: 1 % of the frames written twice;
- ``gap1s``: the frequency blank for one second (30 s to 31 s), bridged by the config's
  ``gaps = { max = 1.5 }`` (its outputs then leave the fit);
- ``stat0.5``: 0.5 % of the frames flagged invalid by a C37.118 STAT word, their values 0.

For each, on P_e (H documented) and on P_m (``mechanical.csv``: the governor's output with
the same noise), what ``rapid-cosim structures`` and ``diagnose`` decide: the structure
(TG Type I, TGOV1, IEEEG1), the diagnosis of the event's own config (its documented
governor and the effect catalogue on it): its verdict, the final model's estimates with
their reported standard errors and its variance ratio; and the time per simulation of
the event's bench on the variant's stamps against the same values on regular stamps. The table puts each beside
the clean-stamp run: the estimates' moves in standard errors, the variance ratio's change.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np
from rapid_cosim.compiler.source import ModelSource

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments" / "electrical"))
sys.path.insert(0, str(ROOT / "benchmarks"))

VARIANTS = ("clean", "jitter1", "jitter3", "jitter5", "drop0.1", "drop1", "burst5", "repeat1", "gap1s", "stat0.5")
KINDS = {"pe": "P_e, H fixed", "pm": "P_m recorded"}
GAP = (30.0, 31.0)


def committed() -> list[Path]:
    import generate

    return [ROOT / "experiments" / "electrical" / e.name for e in generate.COMMITTED]


def andes(folder: Path, work: Path) -> dict[str, np.ndarray]:
    """ANDES's noise-free run of the event (cached: 30 s a run)."""
    import generate

    cache = work / "andes" / f"{folder.name}.npz"
    if not cache.exists():
        event = next(e for e in generate.COMMITTED if e.name == folder.name)
        cache.parent.mkdir(parents=True, exist_ok=True)
        np.savez(cache, **generate.andes_run(event))
    return dict(np.load(cache))


def recorded(folder: Path, name: str, run: dict, seed: int) -> dict[str, list[str]]:
    """The variant's rows of data.csv and mechanical.csv (header first) and its config."""
    import generate

    data = np.genfromtxt(folder / "data.csv", delimiter=",", names=True)
    clean = np.genfromtxt(folder / "clean.csv", delimiter=",", names=True)
    mech = np.genfromtxt(folder / "mechanical.csv", delimiter=",", names=True)
    t = data["time"]
    f_noise, p_noise = data["FREQ"] - clean["FREQ"], data["P"] - clean["P"]
    pm_noise = mech["P"] - generate.SN * np.interp(t, run["t"], run["pout"])
    rng = np.random.default_rng([seed, *(ord(c) for c in name)])
    parts = name.split("+")
    stamps = t.copy()
    keep = np.ones(t.size, dtype=bool)
    for part in parts:
        if part.startswith("jitter"):
            j = float(part[len("jitter"):]) * 1e-3
            stamps = t + rng.uniform(-j, j, t.size)
            stamps[0] = max(stamps[0], 0.0)
        elif part.startswith("drop"):
            share = float(part[len("drop"):]) / 100
            keep[rng.choice(np.arange(1, t.size - 1), max(1, int(round(share * t.size))), replace=False)] = False
        elif part == "burst5":
            for start in rng.choice(np.arange(60, t.size - 60, 30), 4, replace=False):
                keep[start:start + 5] = False
    f = generate.F_NOM * np.interp(stamps, run["t"], run["w"]) + f_noise
    pe = generate.SN * np.interp(stamps, run["t"], run["pe"]) + p_noise
    pm = generate.SN * np.interp(stamps, run["t"], run["pout"]) + pm_noise
    stat = np.zeros(t.size, dtype=int)
    if name == "stat0.5":
        bad = rng.choice(np.arange(1, t.size - 1), int(round(0.005 * t.size)), replace=False)
        stat[bad] = 0x8000
        f[bad], pe[bad], pm[bad] = 0.0, 0.0, 0.0
    blank = (stamps >= GAP[0]) & (stamps < GAP[1]) if name == "gap1s" else np.zeros(t.size, dtype=bool)
    repeat = set(rng.choice(np.arange(t.size), int(round(0.01 * t.size)), replace=False).tolist()) \
        if name == "repeat1" else set()
    head = "time,FREQ,P" + (",STAT" if name == "stat0.5" else "")
    out = {"data.csv": [head], "mechanical.csv": [head]}
    for k in np.flatnonzero(keep):
        freq = "" if blank[k] else f"{f[k]:.6f}"
        extra = f",{stat[k]}" if name == "stat0.5" else ""
        rows = {"data.csv": f"{stamps[k]:.6f},{freq},{pe[k]:.3f}{extra}",
                "mechanical.csv": f"{stamps[k]:.6f},{freq},{pm[k]:.3f}{extra}"}
        for file, row in rows.items():
            out[file] += [row, row] if k in repeat else [row]
    if name == "clean":  # the committed files themselves
        out = {file: (folder / file).read_text().splitlines() for file in out}
    return out


def write_variant(folder: Path, name: str, work: Path) -> Path:
    truth = json.loads((folder / "truth.json").read_text())
    target = work / "events" / folder.name / name
    if (target / "config.toml").exists():
        return target
    target.mkdir(parents=True, exist_ok=True)
    for file, rows in recorded(folder, name, andes(folder, work), truth["seed"]).items():
        (target / file).write_text("\n".join(rows) + "\n")
    for file in ("clean.csv", "truth.json"):
        shutil.copy(folder / file, target / file)
    text = (folder / "config.toml").read_text()
    if name == "gap1s":
        text = text.replace('baseline = "pre-event" }', 'baseline = "pre-event", gaps = { max = 1.5 } }')
    if name == "stat0.5":
        text = text.replace("outputs =", 'flags = { column = "STAT", kind = "c37.118" }\noutputs =')
    (target / "config.toml").write_text(text)
    return target


UNIT_VARIANT = "jitter3+drop0.5"  # the identification's untidy recordings


def unit_check(work: Path) -> dict:
    """``experiments/electrical/unit.toml`` identified on its committed recordings and on
    the same with +-3 ms jitter and 0.5 % of the frames dropped (same noise draw): the
    recommended record, its parameters with their standard errors, the held-out RMSE over
    the noise."""
    import rapid_cosim as rc

    unit = ROOT / "experiments" / "electrical" / "unit.toml"
    text = unit.read_text()
    out = {}
    for name in ("clean", UNIT_VARIANT):
        folder = work / "unit" / name
        (folder / "structures").mkdir(parents=True, exist_ok=True)
        for structure in (ROOT / "experiments" / "electrical" / "structures").glob("*.toml"):
            shutil.copy(structure, folder / "structures")
        configs = []
        for event in ("tgtypei_on", "tgtypei_off_same"):
            source = write_variant(ROOT / "experiments" / "electrical" / event, name, work)
            configs.append(str(source.resolve()))
        body = text.replace('configs = ["tgtypei_on", "tgtypei_off_same"]',
                            "configs = [" + ", ".join(f'"{c}"' for c in configs) + "]")
        body = body.replace('holdout = ["tgtypei_off_same"]', 'holdout = ["tgtypei_off_same"]')
        (folder / "unit.toml").write_text(body)
        t0 = time.perf_counter()
        result = rc.identify(folder / "unit.toml", workdir=folder / "results", report=False, log=lambda *_: None)
        record = result.record(result.recommended) if result.recommended else None
        out[name] = {"recommended": result.recommended, "fit": record.fit if record else None,
                     "parameters": record.parameters if record else {},
                     "se": {k: abs(record.parameters[k]) * v for k, v in record.relative_se.items()} if record else {},
                     "heldout": {t: record.tests[t].rmse_over_noise for t in result.heldout} if record else {},
                     "explanation": result.explanation.verdict, "seconds": time.perf_counter() - t0}
    return out


def judge(folder: Path, kind: str, work: Path) -> dict:
    """Structure selection (TG Type I, TGOV1, IEEEG1), and the diagnosis of the event's
    own config (its documented governor, the effect catalogue on it): its verdict, the
    final model's estimates with their standard errors (the reported 90 % intervals over
    1.645) and its variance ratio."""
    from electrical_study import candidate_structures, variant

    import rapid_cosim as rc
    from rapid_cosim.calibration import RunOptions
    from rapid_cosim.structures.select import select_structure

    exp = variant(folder, KINDS[kind])
    scratch = work / "runs" / folder.parent.name / folder.name / kind
    t0 = time.perf_counter()
    verdict = select_structure(candidate_structures(), [exp], workdir=scratch / "structures",
                               options=RunOptions(method="ms", seed=1), source=ModelSource(fmu_dir=ROOT / "fmus"), log=lambda *_: None)
    d = rc.diagnose([exp], workdir=scratch / "diagnosis", seed=1, source=ModelSource(package=ROOT / "modelica" / "iGrGen", fmu_dir=ROOT / "fmus"), log=lambda *_: None)
    se = {k: (hi - lo) / 2 / 1.645 for k, (lo, hi) in d.parameter_intervals.items()}
    return {"structure": verdict.structure, "candidates": verdict.candidates, "effect": d.named.verdict,
            "parameters": d.parameters_after, "se": se,
            "variance_ratio": d.adequacy.after.pooled_variance_ratio, "seconds": time.perf_counter() - t0,
            "recording": exp.recording.lines()}


def simulation_cost(folder: Path, repeats: int = 7) -> dict:
    """Time per simulation of the event's bench on the variant's stamps against the same
    input values on regular stamps (P_e scored samples, the exponential runner, batches of
    20 and single calls), and the largest difference between the two runs' outputs."""
    from electrical_study import variant
    from timing import best

    from rapid_cosim.simulator import get_simulator
    from rapid_cosim.compiler import ensure_fmu

    exp = variant(folder, KINDS["pe"])
    table = exp.input_table
    sim = get_simulator(ensure_fmu(exp.model, fmu_dir=ROOT / "fmus"))
    values = {**exp.fixed}
    regular_t = table.time[0] + (table.time[-1] - table.time[0]) * np.arange(table.time.size) / (table.time.size - 1)
    inputs = {n: table.values[:, k] for k, n in enumerate(table.names)}
    times = exp.windowed_data().time
    out = {}
    for label, grid in (("stamps", table.time), ("regular", regular_t)):
        single = best(lambda: sim.simulate(values, output_times=grid, input_time=grid, inputs=inputs,
                                           outputs=["pe"], check=False), repeats)
        out[label] = single
    out["ratio"] = out["stamps"] / out["regular"]
    out["samples"] = int(times.size)
    return out


def table_rows(results: dict) -> list[str]:
    """One Markdown row per event, kind and variant, against the event's clean stamps."""
    lines = []
    for event, variants in results.items():
        for kind in KINDS:
            if kind not in variants.get("clean", {}):
                continue
            base = variants["clean"][kind]
            for name, r in variants.items():
                if kind not in r:
                    continue
                j = r[kind]
                moves = [abs(j["parameters"][p] - base["parameters"][p]) / base["se"][p]
                         for p in base["se"] if base["se"][p] > 0]
                lines.append(f"| {event} | {kind} | {name} | {j['structure']} | {j['effect']} | "
                             + ", ".join(f"{p.split('.')[-1]} {v:.4g}" for p, v in j["parameters"].items())
                             + f" | {max(moves):.2f} | {j['variance_ratio']:.3f} | "
                             f"{j['variance_ratio'] - base['variance_ratio']:+.3f} | "
                             f"{r.get('cost', {}).get('ratio', float('nan')):.2f} |")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, default=ROOT / "results" / "bench-timebase")
    parser.add_argument("--events", help="comma-separated event names (default: every committed one)")
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--kinds", default="pe,pm")
    parser.add_argument("--unit", action="store_true", help="also identify experiments/electrical/unit.toml on "
                                                            f"clean and {UNIT_VARIANT} stamps")
    args = parser.parse_args(argv)
    events = [f for f in committed() if not args.events or f.name in args.events.split(",")]
    names = args.variants.split(",")
    kinds = args.kinds.split(",")
    results_file = args.work / "study.json"
    results = json.loads(results_file.read_text()) if results_file.exists() else {}
    for folder in events:
        for name in names:
            target = write_variant(folder, name, args.work)
            entry = results.setdefault(folder.name, {}).setdefault(name, {})
            for kind in kinds:
                if kind not in entry:
                    entry[kind] = judge(target, kind, args.work)
                    print(f"{folder.name} {name} {kind}: {entry[kind]['structure']}, {entry[kind]['effect']}, "
                          f"variance ratio {entry[kind]['variance_ratio']:.3f} ({entry[kind]['seconds']:.0f} s)",
                          flush=True)
            if "cost" not in entry:
                entry["cost"] = simulation_cost(target)
            results_file.write_text(json.dumps(results, indent=1) + "\n")  # resumable: done parts are kept
    print("\n| event | kind | stamps | structure | effect | estimates | largest move (SE) | variance ratio | "
          "change | sim. time ratio |")
    print("|---|---|---|---|---|---|---:|---:|---:|---:|")
    for line in table_rows(results):
        print(line)
    if args.unit:
        results["unit"] = unit = unit_check(args.work)
        results_file.write_text(json.dumps(results, indent=1) + "\n")
        clean, untidy = unit["clean"], unit[UNIT_VARIANT]
        moves = {p: abs(untidy["parameters"][p] - v) / clean["se"][p] for p, v in clean["parameters"].items()
                 if clean["se"].get(p)}
        print(f"\nunit.toml on its committed recordings: {clean['recommended']} ({clean['fit']}), explanation "
              f"{clean['explanation']}, held out {clean['heldout']}")
        print(f"the same with +-3 ms jitter and 0.5 % of the frames dropped: {untidy['recommended']} ({untidy['fit']}), "
              f"explanation {untidy['explanation']}, held out {untidy['heldout']}; largest move "
              f"{max(moves.values(), default=0):.2f} SE ({', '.join(f'{p} {m:.2f}' for p, m in moves.items())})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
