"""Delivered records put back into ANDES in closed loop (issue 40): ``make bench-replay``.

    python benchmarks/replay_study.py --work results/bench-replay [--fleet-units 20]

A record is right when a grid simulator nobody here wrote, reading the file, does what
the plant did. Each delivered ``unit.dyr`` goes into ANDES 2.0's Kundur grid as
generator 1's governor (``experiments/electrical/andes_grid.py``: ANDES's own parser, its
departures from PSS/E converted and named) and every event of its unit is run again in
closed loop: the rotor swing and the network are ANDES's. The replay's electrical power
is compared, from the event to the end, with the true plant's own replay (noise-free):

- **RMSE / noise**: the RMSE of the difference over the recorder's noise level (as
  identify estimates it from the unit's quiet data), the held-out event first;
- **largest error / excursion**: the largest difference as a share of the plant's
  largest excursion of P_e from its value before the event.

Beside each record, the same figures for the true plant's own record (written by the
project's writer: the pipeline's floor, near zero when writer and conversions are right)
and, for an IEEEG1 record whose fit took K3 from ``K3_rest``, the record as the writer
wrote it before issue 40 (its K3 at the table's 0.3).

The units:

1. **The steam unit** (``experiments/steam``: ANDES's IEEEG1, K 20, K1 0.3, K3 0.7, T5 8 s,
   a 0.5 s governor lag, an opening rate of 0.015 pu/s that binds; three events, the third
   held out) recorded three ways, the same noise on each: the committed regular stamps;
   every stamp moved within +-3 ms; PMU-style (1 % of the frames repeated, 1 % dropped,
   0.5 % flagged invalid by a C37.118 STAT word, their values 0). Each identified by
   ``rc.identify`` (rapid-cosim identify's function).
2. **The electrical unit** (``experiments/electrical/unit.toml``: TG Type I, R 0.05, Ts
   0.8 s, T5 7 s, run in ANDES as the IEEEG1 it equals; two events, one held out).
3. **The deadband unit** (``experiments/deadband``: ANDES's TGOV1DB, R 0.05, T1 0.4, T2 1.5,
   T3 6, a no-step band of +-0.0006 pu, 36 mHz at 60 Hz): ``unit.toml`` (events of two
   sizes, 200 MW switched off held out) and ``one_size.toml`` (the steam unit's three
   events, one size each way: the band not determined), each replayed on all four
   recorded events and a fifth of 50 MW, whose frequency leaves the band by about a
   third of its width. Beside the delivered record: the same unit's TGOV1 fitted without
   a deadband, and the droop and band each record states against the plant's.
4. **The gas unit** (``experiments/gas``: ANDES's GAST, R 0.05, T1 0.4, T2 0.1; its
   three events, one held out).
5. **A synthetic fleet** (``rapid_cosim.fleet.synthetic``, ``--fleet-units`` units, seed 1)
   run by ``rc.fleet``; every unit it identifies whose plant is a TGOV1, an IEEEG1 or a TG
   Type I (the IEEEG1 it equals) and whose recommended record is a TGOV1 or an IEEEG1,
   replayed on the fleet's event (200 MW switched on at bus 7). The fleet's plants
   were made on ANDES's frequency in open loop; here plant and record both run in
   ANDES's closed loop.

ANDES runs are cached in the work folder by the record's text and the event.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import sys
import time
from pathlib import Path

import numpy as np
from rapid_cosim.fitting.engine import EngineSpec
from rapid_cosim.compiler.source import ModelSource

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments" / "electrical"))

VARIANTS = ("regular", "jitter3", "pmu")
DEADBAND_UNITS = ("unit.toml", "one_size.toml")
OLD_K3 = 0.3  # what the writer put in K3 before issue 40 where K3_rest was 1 (the table's default)
GENERATOR_BUS = 1


# --- ANDES -------------------------------------------------------------------------------

def steam_generator():
    """experiments/steam/generate.py (its name is the electrical events' generator's too)."""
    import importlib.util

    if "steam_generate" not in sys.modules:
        spec = importlib.util.spec_from_file_location("steam_generate", ROOT / "experiments" / "steam" / "generate.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules["steam_generate"] = module
        spec.loader.exec_module(module)
    return sys.modules["steam_generate"]


def on_generator_1(record: str) -> str:
    """The record moved to bus 1 (generator 1 of Kundur's case: a fleet unit's record names
    its own bus), its numbers untouched."""
    return re.sub(r"^\s*\d+", str(GENERATOR_BUS), record, count=1)


def _cache(record: str, event, work: Path) -> Path:
    return work / "andes" / f"{hashlib.sha256((record + repr(event)).encode()).hexdigest()[:16]}.npz"


def _run_into(record: str, event, cache: Path) -> None:
    import andes_grid

    run = andes_grid.run_record(record, event)
    cache.parent.mkdir(parents=True, exist_ok=True)
    np.savez(cache, t=run["t"], w=run["w"], pe=run["pe"], pout=run["pout"])


def replays(pairs: list[tuple[str, object]], work: Path) -> None:
    """ANDES's runs of every (record, event) not cached yet, two at a time (one a core)."""
    import joblib

    pairs = [(on_generator_1(r), e) for r, e in pairs]
    todo = {_cache(r, e, work): (r, e) for r, e in pairs if not _cache(r, e, work).exists()}
    joblib.Parallel(n_jobs=2)(joblib.delayed(_run_into)(r, e, c) for c, (r, e) in todo.items())


def replay(record: str, event, work: Path) -> dict[str, np.ndarray]:
    """ANDES's closed-loop run of ``event`` with ``record`` on generator 1 (cached)."""
    record = on_generator_1(record)
    cache = _cache(record, event, work)
    if not cache.exists():
        _run_into(record, event, cache)
    return dict(np.load(cache))


def andes_plant(model: str, values: dict[str, float]) -> str:
    """A plant in this project's names (machine base; IEEEG1's K3 already the one in use)
    as a record composed from ANDES's own field list."""
    import andes_grid

    from rapid_cosim.exchange import model_named

    table = model_named(model)
    full = {f.param: values.get(f.param, f.default) for f in table.fields if f.param}
    names = {"Uo": "UO", "Uc": "UC"}
    given = {names.get(k, k): v for k, v in full.items()}
    if model == "IEEEG1":
        given.update(K2=0.0, K4=0.0, K6=0.0, K8=0.0, T1=max(given["T1"], 0.0))
    return andes_grid.andes_record(model, given)


def figures(run: dict, truth: dict, sigma: float, t_event: float) -> dict[str, float]:
    """RMSE over the noise and the largest error over the excursion, from the event on."""
    after = truth["t"] >= t_event
    pe = np.interp(truth["t"], run["t"], run["pe"])
    before = float(np.interp(t_event - 0.05, truth["t"], truth["pe"]))
    diff = (pe - truth["pe"])[after]
    excursion = float(np.max(np.abs(truth["pe"][after] - before)))
    return {"rmse_over_noise": float(np.sqrt(np.mean(diff ** 2)) / sigma),
            "largest_share": float(np.max(np.abs(diff)) / excursion)}


def old_record(text: str) -> str | None:
    """The delivered IEEEG1 record as the writer wrote it before issue 40 (K3 at 0.3),
    where its K3 was the rest of the shaft; None otherwise."""
    from rapid_cosim.exchange import psse_dyr

    (record,), _ = psse_dyr.parse_records(text)
    if record.model != "IEEEG1" or abs(record.values["K1"] + record.values["K3"] + record.values["K5"]
                                       + record.values["K7"] - 1.0) > 1e-12:
        return None
    values = {k: v for k, v in record.values.items() if k != "K3_rest"}
    return psse_dyr.format_record("IEEEG1", {**values, "K3": OLD_K3}, bus=record.bus,
                                  machine_id=record.machine_id)[0]


def noise_levels(configs: list[Path]) -> dict[str, float]:
    """Per test, the recorder's noise level (pu) as identify estimates it."""
    from rapid_cosim.diagnose.selection import noise_floors
    from rapid_cosim.experiment import load_experiment
    from rapid_cosim.noise import campaign_noise

    experiments = [load_experiment(c) for c in configs]
    floors = noise_floors(experiments, campaign_noise(experiments))
    return {e.name: float(floors[e.name].sigma) for e in experiments}


def judge(label: str, delivered: str, plant: str, events: dict, sigmas: dict, heldout: list[str],
          work: Path, also: dict[str, str] | None = None) -> dict:
    """The delivered record, the plant's own and the old writer's (or ``also``, other
    records by name), on every event."""
    rows = {}
    candidates = {"delivered": delivered, "plant's own": plant_own(plant),
                  **(also if also is not None else {"before issue 40": old_record(delivered)})}
    replays([(text, e) for e in events.values() for text in (plant, *candidates.values()) if text is not None], work)
    for name, event in events.items():
        truth = replay(plant, event, work)
        rows[name] = {which: figures(replay(text, event, work), truth, sigmas[name], event.t_event)
                      for which, text in candidates.items() if text is not None}
    return {"unit": label, "heldout": heldout, "events": rows}


def plant_own(plant: str) -> str:
    """The plant's record as this project's writer writes it (read by this project's
    reader from ANDES's composition, written again)."""
    from rapid_cosim.exchange import psse_dyr

    (record,), _ = psse_dyr.parse_records(plant)
    return psse_dyr.format_record(record.model, record.values, bus=record.bus, machine_id=record.machine_id)[0]


# --- the units ----------------------------------------------------------------------------

def identify(unit: Path, workdir: Path):
    import rapid_cosim as rc

    t0 = time.perf_counter()
    result = rc.identify(unit, workdir=workdir, engine=EngineSpec(n_jobs=2), report=False, log=lambda *_: None)
    return result, time.perf_counter() - t0


def steam_variant(name: str, work: Path) -> Path:
    """The steam unit's folder recorded as ``name`` (module docstring), the same noise."""
    import generate as electrical

    steam = steam_generator()
    home = ROOT / "experiments" / "steam"
    folder = work / "steam" / name
    if name == "regular":
        return home / "unit.toml"
    if (folder / "unit.toml").exists():
        return folder / "unit.toml"
    replays([(steam.plant_record(), event) for event, _ in steam.EVENTS.values()], work)
    for event_name, (event, seed) in steam.EVENTS.items():
        source = home / event_name
        data = np.genfromtxt(source / "data.csv", delimiter=",", names=True)
        clean = np.genfromtxt(source / "clean.csv", delimiter=",", names=True)
        run = replay(steam.plant_record(), event, work)
        rng = np.random.default_rng([seed, 3])
        t = data["time"]
        stamps = t + (rng.uniform(-3e-3, 3e-3, t.size) if name == "jitter3" else 0.0)
        stamps[0] = max(stamps[0], 0.0)
        f = electrical.F_NOM * np.interp(stamps, run["t"], run["w"]) + data["FREQ"] - clean["FREQ"]
        p = electrical.SN * np.interp(stamps, run["t"], run["pe"]) + data["P"] - clean["P"]
        rows = ["time,FREQ,P" + (",STAT" if name == "pmu" else "")]
        if name == "jitter3":
            rows += [f"{a:.6f},{b:.6f},{c:.3f}" for a, b, c in zip(stamps, f, p)]
        else:  # PMU-style: repeats, drops, STAT-invalid frames
            inner = np.arange(1, t.size - 1)
            dropped = set(rng.choice(inner, int(0.01 * t.size), replace=False).tolist())
            repeated = set(rng.choice(inner, int(0.01 * t.size), replace=False).tolist())
            invalid = set(rng.choice(inner, int(0.005 * t.size), replace=False).tolist())
            for k in range(t.size):
                if k in dropped:
                    continue
                row = (f"{stamps[k]:.6f},0.000000,0.000,32768" if k in invalid
                       else f"{stamps[k]:.6f},{f[k]:.6f},{p[k]:.3f},0")
                rows += [row, row] if k in repeated else [row]
        target = folder / event_name
        target.mkdir(parents=True, exist_ok=True)
        (target / "data.csv").write_text("\n".join(rows) + "\n")
        text = (source / "config.toml").read_text()
        if name == "pmu":
            text = text.replace("outputs =", 'flags = { column = "STAT", kind = "c37.118" }\noutputs =')
        (target / "config.toml").write_text(text)
    unit = (home / "unit.toml").read_text().replace('"../electrical/structures/',
                                                     f'"{ROOT / "experiments" / "electrical" / "structures"}/')
    (folder / "unit.toml").write_text(unit)
    return folder / "unit.toml"


def steam_rows(work: Path, variants=VARIANTS) -> list[dict]:
    steam = steam_generator()
    out = []
    for name in variants:
        unit = steam_variant(name, work)
        result, seconds = identify(unit, work / "identify" / f"steam-{name}")
        text = Path(result.files["dyr"]).read_text()
        configs = [unit.parent / e for e in steam.EVENTS]
        row = judge(f"steam unit, {name} stamps", text, steam.plant_record(),
                    {e: ev for e, (ev, _) in steam.EVENTS.items()}, noise_levels(configs), result.heldout, work)
        row.update(record=result.recommended, fit=result.record(result.recommended).fit, seconds=seconds,
                   dyr=text)
        out.append(row)
    return out


def electrical_rows(work: Path) -> list[dict]:
    import andes_grid
    import generate as electrical

    unit = ROOT / "experiments" / "electrical" / "unit.toml"
    result, seconds = identify(unit, work / "identify" / "electrical")
    text = Path(result.files["dyr"]).read_text()
    plant = {**electrical.tgtypei_as_ieeeg1({"R": 0.05, "Ts": 0.8, "T5": 7.0})}
    events = {"tgtypei_on": andes_grid.GridEvent(load=+1), "tgtypei_off_same": andes_grid.GridEvent(load=-1)}
    configs = [unit.parent / e for e in events]
    row = judge("electrical unit (TG Type I)", text, andes_plant("IEEEG1", plant), events, noise_levels(configs),
                result.heldout, work)
    row.update(record=result.recommended, fit=result.record(result.recommended).fit, seconds=seconds, dyr=text)
    return [row]


def _generator(folder: str):
    """experiments/<folder>/generate.py, loaded under a name of its own."""
    import importlib.util

    name = f"{folder}_generate"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "experiments" / folder / "generate.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def _plain_record(result, model: str, folder: Path) -> str:
    """The unit's ``model`` fitted without its optional parts, as the record export writes."""
    import rapid_cosim as rc

    archive = Path(result.record(model).archive).parent / f"{model}.h5"
    return rc.export(archive, folder / f"{model}-plain.dyr", bus=GENERATOR_BUS).text


def deadband_events() -> tuple[dict, dict[str, float]]:
    """The deadband unit's events (its recorded ones and the 50 MW one) and noise levels."""
    gen = _generator("deadband")
    events = {name: ev for name, (ev, _) in gen.EVENTS.items()} | {"50 MW at bus 9": gen.SMALL}
    sigmas = noise_levels([ROOT / "experiments" / "deadband" / n for n in gen.EVENTS])
    sigmas["50 MW at bus 9"] = float(np.mean(list(sigmas.values())))  # the same recorder
    return events, sigmas


def gas_events() -> tuple[dict, dict[str, float]]:
    """The gas unit's recorded events and noise levels."""
    gen = _generator("gas")
    events = {name: ev for name, (ev, _) in gen.EVENTS.items()}
    return events, noise_levels([ROOT / "experiments" / "gas" / n for n in events])


def deadband_rows(work: Path, units=DEADBAND_UNITS) -> list[dict]:
    """The deadband unit of each unit file, identified and replayed on every event with
    the 50 MW one, beside its TGOV1 fitted without a deadband."""
    from rapid_cosim.exchange import psse_dyr

    gen = _generator("deadband")
    home = ROOT / "experiments" / "deadband"
    events, sigmas = deadband_events()
    out = []
    for file in units:
        stem = Path(file).stem
        result, seconds = identify(home / file, work / "identify" / f"deadband-{stem}")
        text = Path(result.files["dyr"]).read_text()
        also = {"TGOV1, no deadband": _plain_record(result, "TGOV1", work / "identify" / f"deadband-{stem}")}
        row = judge(f"deadband unit ({stem})", text, gen.plant_record(), events, sigmas, result.heldout, work, also)
        (stated,), _ = psse_dyr.parse_records(text)
        (plain,), _ = psse_dyr.parse_records(also["TGOV1, no deadband"])
        row.update(record=result.recommended, fit=result.record(result.recommended).fit, seconds=seconds, dyr=text,
                   stated={"delivered": _against(stated.values, gen.PLANT),
                           "TGOV1, no deadband": _against(plain.values, gen.PLANT)},
                   held_to_bar=file == "unit.toml", story=result.story())
        out.append(row)
    return out


def _against(values: dict, plant: dict) -> dict[str, float]:
    """The droop and band a record states, as shares off the plant's (TGOV1D's fields)."""
    return {"R": values["R"] / plant["R"] - 1, "db": values.get("db", 0.0) / plant["dbH"] - 1}


def gas_rows(work: Path) -> list[dict]:
    gen = _generator("gas")
    home = ROOT / "experiments" / "gas"
    result, seconds = identify(home / "unit.toml", work / "identify" / "gas")
    text = Path(result.files["dyr"]).read_text()
    events, sigmas = gas_events()
    row = judge("gas unit (GAST)", text, gen.plant_record(), events, sigmas, result.heldout, work, {})
    row.update(record=result.recommended, fit=result.record(result.recommended).fit, seconds=seconds, dyr=text)
    return [row]


def fleet_rows(work: Path, units: int) -> list[dict]:
    import andes_grid

    import rapid_cosim as rc
    from rapid_cosim.exchange import model_named
    from rapid_cosim.fleet.synthetic import PRE_EVENT_S, make_fleet
    from rapid_cosim.structures.structure import Structure

    folder = work / "fleet"
    spec = folder / "fleet.toml"
    if not spec.exists():
        make_fleet(folder, units, experiments=ROOT / "experiments", seed=1, source=ModelSource(fmu_dir=ROOT / "fmus"))
    result = rc.fleet(spec, results=folder / "results", engine=EngineSpec(n_jobs=2, backend="dask"), progress=False)
    event = andes_grid.GridEvent(load=+1, t_event=PRE_EVENT_S, duration=60.0 - 10.0 + PRE_EVENT_S)
    out = []
    for u in result.units:
        u = u.to_json()
        if u["route"] != "identified" or not u.get("recommended"):
            continue
        home = Path(u["folder"])
        truth = json.loads((home / "truth.json").read_text())
        model = {"TGOV1": "TGOV1", "IEEEG1": "IEEEG1", "TGTypeI": "IEEEG1"}.get(truth["structure"])
        if model is None or u["recommended"]["model"] not in ("TGOV1", "IEEEG1"):
            continue
        structure = Structure.load(home / "structures" / f"{model}.toml")
        values = {k.removeprefix("gov."): v for k, v in structure.fixed.items()} | truth["plant"]
        resolve = model_named(model).resolve  # the stages in use written into K3, as a delivered record has it
        values = resolve(values) if resolve else values
        values.pop("K3_rest", None)
        text = (folder / "results" / u["files"]["dyr"]).read_text()
        row = judge(f"{u['unit']} ({truth['structure']})", text, andes_plant(model, values),
                    {"event": event}, {"event": _unit_sigma(home)}, [], work)
        row.update(record=u["recommended"]["model"], fit=u["recommended"]["fit"], seconds=u["seconds"], dyr=text)
        out.append(row)
    return out


def _unit_sigma(home: Path) -> float:
    from rapid_cosim.experiment import load_experiment

    exp = load_experiment(home / "event")
    return noise_levels([home / "event"])[exp.name]


# --- the table ----------------------------------------------------------------------------

def lines(rows: list[dict]) -> list[str]:
    out = [f"{'unit':<34} {'record':<22} {'event':<17} {'delivered':>17} {'plant own':>17} {'other record':>17}",
           f"{'':<34} {'':<22} {'':<17} {'RMSE/noise  max':>17} {'RMSE/noise  max':>17} {'RMSE/noise  max':>17}"]
    for row in rows:
        first = True
        other = next((k for f in row["events"].values() for k in f if k not in ("delivered", "plant's own")), None)
        if other:
            out.append(f"{'':<34} {'':<22} {'':<17} {'':>17} {'':>17} {other:>18}")
        for name, figs in sorted(row["events"].items(), key=lambda kv: kv[0] not in row["heldout"]):
            cells = []
            for which in ("delivered", "plant's own", other):
                f = figs.get(which)
                cells.append(f"{f['rmse_over_noise']:7.3f} {100 * f['largest_share']:6.1f} %" if f else f"{'-':>17}")
            label = name + (" (held out)" if name in row["heldout"] else "")
            out.append(f"{row['unit'] if first else '':<34} {row['fit'] if first else '':<22} {label:<17} "
                       + " ".join(f"{c:>17}" for c in cells))
            first = False
    return out


def verdict(rows: list[dict]) -> list[str]:
    """The issue's bar on the units identified with a held-out event (the steam unit's
    three recordings, the electrical unit): each held-out event within 0.3 of the noise
    (RMSE) and 5 % of the excursion (largest error); then the fleet's units, each replayed
    on its own (training) event in ANDES's closed loop."""
    out = []
    rows, apart = [r for r in rows if r.get("held_to_bar", True)], [r for r in rows if not r.get("held_to_bar", True)]
    for r in apart:  # a unit whose recordings do not determine its effect: its story says so
        f = next(f["delivered"] for name, f in r["events"].items() if name in r["heldout"])
        out.append(f"{r['unit']} (not held to the bar: its recordings do not determine the band, and its story says "
                   f"so): held out {f['rmse_over_noise']:.3f} of the noise, {100 * f['largest_share']:.1f} %")
    for label, chosen in (("held-out events", [r for r in rows if r["heldout"]]),
                          ("fleet units, their own event in closed loop", [r for r in rows if not r["heldout"]])):
        figs = [(r["unit"], f["delivered"]) for r in chosen for name, f in r["events"].items()
                if name in r["heldout"] or not r["heldout"]]
        if not figs:
            continue
        bad = [u for u, f in figs if f["rmse_over_noise"] > 0.3 or f["largest_share"] > 0.05]
        top = max(f["rmse_over_noise"] for _, f in figs)
        share = max(f["largest_share"] for _, f in figs)
        out.append(f"{label}: worst {top:.3f} of the noise, {100 * share:.1f} % of the excursion; within 0.3 and "
                   f"5 %: {len(figs) - len(bad)} of {len(figs)}" + (f" (not: {', '.join(bad)})" if bad else ""))
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", default="results/bench-replay")
    parser.add_argument("--fleet-units", type=int, default=20)
    parser.add_argument("--parts", default="steam,electrical,deadband,gas,fleet")
    parser.add_argument("--variants", default=",".join(VARIANTS), help="the steam unit's recordings")
    parser.add_argument("--json", help="write every figure here")
    args = parser.parse_args(argv)
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    parts = args.parts.split(",")
    t0 = time.perf_counter()
    rows = []
    if "steam" in parts:
        rows += steam_rows(work, args.variants.split(","))
    if "electrical" in parts:
        rows += electrical_rows(work)
    if "deadband" in parts:
        rows += deadband_rows(work)
    if "gas" in parts:
        rows += gas_rows(work)
    if "fleet" in parts:
        rows += fleet_rows(work, args.fleet_units)
    print("\n".join(lines(rows)))
    print("\n".join(verdict(rows)))
    for row in rows:
        for which, off in row.get("stated", {}).items():
            print(f"{row['unit']}, {which}: droop {100 * off['R']:+.1f} %, deadband {100 * off['db']:+.1f} % "
                  "off the plant's")
    for row in rows:
        print(f"{row['unit']}: {row['fit']}, identified in {row['seconds']:.0f} s\n    " + row["dyr"].replace("\n", "\n    "))
    print(f"make bench-replay: {time.perf_counter() - t0:.0f} s")
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(rows, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
