"""A synthetic fleet for the tests and the benchmark: units of the four standard structures
and TG Type I, one grid event driving them all, each with a record on file that is right
for half of them and wrong for the other half.

What is invented here, and how:

- **The event.** One committed ANDES event's noise-free frequency
  (``experiments/electrical/tgov1_on``: 200 MW switched on in the Kundur grid, 60 Hz, 30
  frames/s, 60 s, 10 s of them before the event), its steady state held for
  :data:`PRE_EVENT_S` before the event in all: every unit sees the same grid frequency,
  through its own PMU's noise (1 mHz, correlated over 0.3 s,
  :func:`rapid_cosim.experiment.synthetic.pmu_noise`). Why 30 s before the event: on an
  event that is the only quiet data the recorder's noise is estimated from, and PMU
  archives are continuous, so an operator can take it. With 10 s the noise tests' p
  cannot be trusted either way: on the 30 s recordings' last 10 s, two right records of
  50 were rejected at p 7e-11 and 4e-8 (on another noise draw, a wrong record 1.4 noise
  levels off passed at p 0.13); ``make bench-fleet`` plays the records back on both.
- **The plants** (structure ``k % 5``): parameters drawn across the structure files'
  ranges where real units sit (droop 4-7 %, lags and water columns in their usual
  spans), the documented constants the unit's structure file gives. A TG Type I plant is
  run as the IEEEG1 it equals between its limits (IEEEG1's T1 = Tc, T2 = T3, T3 = Ts,
  K1 = T4 / T5, a 1 ms steam chest), its structure file documenting that lead-lag. A
  quarter of the units (IEEEG1, GGOV1 and TG Type I units, each with probability 25/60)
  has a valve opening rate that binds in the event (IEEEG1's Uo, GGOV1's Ropen), which its
  record on file may not carry.
- **The recorders.** Even units record P_e (H 3-8 s documented), odd ones P_m; in MW on
  a rating of 100-900 MVA; white noise of 0.05-0.1 % of the rating plus a slow
  Ornstein-Uhlenbeck part of 0.3-1 times that (correlation time 0.3-1 s), a meter offset.
- **The record on file**: the plant's own record for units ``k // 5`` even, else wrong in
  one way drawn per unit: its droop (R or 1/K) 30 % off, its main lag twice as long, or
  (for a unit with a binding rate) the rate limit left out.

Each unit is a folder: ``data.csv`` (time, FREQ, P), ``config.toml`` (the event, on TG
Type I's bench with its documented constants: the explanation's base), ``unit.toml``,
``structures/`` (the four standard structure files), ``record.dyr`` and ``truth.json``.

**The mixed fleet** (``make_fleet(..., mixed=True)``, issue 53) is of the families a
planning case holds, the structure ``k % 5``: TGOV1 with a 36 mHz deadband, TGOV1 with a
60 mHz one (0.0006 and 0.001 pu of speed at 60 Hz, the no-step form), GAST gas turbines
(R 4-7 %, fuel valve 0.3-1 s, fuel system 0.05-0.15 s, the PSS/E defaults for the
temperature limit, which does not bind), IEEEG1 and TGOV1 as above, none with a hidden
rate. Each unit states its kind (steam, gas) and takes the shipped standard structures of
it; the deadband units' right records are TGOV1D, and one way a record is wrong is the
deadband left out (a plain TGOV1 record); a GAST record is wrong by its droop or its fuel
valve's lag.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..compiler.source import ModelSource
from ..structures.shipped import kind_files, standard_file

EVENT = Path("electrical") / "tgov1_on"  # under the experiments folder the caller names
STRUCTURES = ("TGOV1", "IEEEG1", "GGOV1", "HYGOV", "TGTypeI")
F_NOM = 60.0
ANDES_PRE_EVENT_S = 10.0  # the committed event's steady state before the load switches on
PRE_EVENT_S = 30.0  # the recordings' span before the event (module docstring)
TGTYPEI_DOC = {"Tc": 0.4, "T3": 0.2, "T4": 1.5, "T5": 6.0}


@dataclass
class UnitPlan:
    name: str
    structure: str  # the plant's
    record_model: str  # the standard model of its record (TG Type I: IEEEG1)
    plant: dict[str, float]  # the record model's values (iGrGen names, no gov.)
    electrical: bool
    rating: float
    h: float
    p_ref: float
    hidden_rate: bool
    record_right: bool
    wrong: str = ""
    record: dict[str, float] = field(default_factory=dict)
    kind: str | None = None  # the unit file's kind (the mixed fleet): its structures are the shipped ones of it


MIXED = ("TGOV1 db36", "TGOV1 db60", "GAST", "IEEEG1", "TGOV1")
DEADBANDS = {"TGOV1 db36": 0.0006, "TGOV1 db60": 0.001}  # pu of speed: 36 and 60 mHz at 60 Hz


def draw_mixed_unit(k: int, seed: int) -> UnitPlan:
    """A unit of the mixed fleet (module docstring)."""
    g = np.random.default_rng([seed, 7919, k])
    structure = MIXED[k % len(MIXED)]
    if structure == "GAST":
        plant, model, kind = {"R": g.uniform(0.04, 0.07), "T1": g.uniform(0.3, 1.0), "T2": g.uniform(0.05, 0.15)}, \
            "GAST", "gas"
    elif structure == "IEEEG1":
        plant, model, kind = {"K": g.uniform(15.0, 25.0), "T3": g.uniform(0.1, 0.8), "T4": g.uniform(0.1, 0.5),
                              "T5": g.uniform(4.0, 10.0), "K1": g.uniform(0.2, 0.4)}, "IEEEG1", "steam"
    else:
        plant, model, kind = {"R": g.uniform(0.04, 0.07), "T1": g.uniform(0.2, 1.5), "T2": g.uniform(0.5, 3.0),
                              "T3": g.uniform(4.0, 10.0)}, "TGOV1", "steam"
        if structure in DEADBANDS:
            plant["db"] = DEADBANDS[structure]
    right = (k // len(MIXED)) % 2 == 0
    plan = UnitPlan(f"unit{k:03d}", structure, model, plant, k % 2 == 0, float(g.uniform(100.0, 900.0)),
                    float(g.uniform(3.0, 8.0)), float(g.uniform(0.55, 0.8)), False, right, kind=kind)
    plan.record = dict(plant)
    if not right:
        ways = ["droop", "lag"] + (["deadband"] if "db" in plant else [])
        plan.wrong = ways[int(g.integers(len(ways)))]
        droop = "K" if model == "IEEEG1" else "R"
        lag = {"TGOV1": "T3", "IEEEG1": "T5", "GAST": "T1"}[model]
        if plan.wrong == "droop":
            plan.record[droop] *= 1.3
        elif plan.wrong == "lag":
            plan.record[lag] *= 2.0
        else:
            plan.record.pop("db")
    return plan


def draw_unit(k: int, seed: int) -> UnitPlan:
    g = np.random.default_rng([seed, k])
    structure = STRUCTURES[k % len(STRUCTURES)]
    hidden = structure in ("IEEEG1", "GGOV1", "TGTypeI") and g.uniform() < 25 / 60  # a quarter of the fleet
    if structure == "TGOV1":
        plant, model = {"R": g.uniform(0.04, 0.07), "T1": g.uniform(0.2, 1.5), "T2": g.uniform(0.5, 3.0),
                        "T3": g.uniform(4.0, 10.0)}, "TGOV1"
    elif structure == "IEEEG1":
        plant, model = {"K": g.uniform(15.0, 25.0), "T3": g.uniform(0.1, 0.8), "T4": g.uniform(0.1, 0.5),
                        "T5": g.uniform(4.0, 10.0), "K1": g.uniform(0.2, 0.4)}, "IEEEG1"
    elif structure == "GGOV1":
        plant, model = {"R": g.uniform(0.04, 0.07), "Kpgov": g.uniform(5.0, 20.0), "Kigov": g.uniform(1.0, 5.0),
                        "Tb": g.uniform(0.3, 1.0), "Ropen": g.uniform(0.1, 0.2), "Rclose": -g.uniform(0.1, 0.2)}, "GGOV1"
    elif structure == "HYGOV":
        plant, model = {"R": g.uniform(0.04, 0.07), "r": g.uniform(0.2, 0.6), "Tr": g.uniform(2.0, 8.0),
                        "TW": g.uniform(0.5, 2.0)}, "HYGOV"
    else:  # TG Type I as the IEEEG1 it equals
        r, ts = g.uniform(0.04, 0.07), g.uniform(0.3, 1.5)
        plant, model = {"K": 1.0 / r, "T3": ts, "T4": 0.001, "T5": TGTYPEI_DOC["T5"],
                        "K1": TGTYPEI_DOC["T4"] / TGTYPEI_DOC["T5"]}, "IEEEG1"
    if hidden and model == "IEEEG1":
        plant.update({"Uo": g.uniform(0.004, 0.008), "Uc": -1.0})
    elif hidden:
        plant["Ropen"] = g.uniform(0.004, 0.008)
    right = (k // len(STRUCTURES)) % 2 == 0
    plan = UnitPlan(f"unit{k:03d}", structure, model, plant, k % 2 == 0, float(g.uniform(100.0, 900.0)),
                    float(g.uniform(3.0, 8.0)), float(g.uniform(0.55, 0.8)), hidden, right)
    plan.record = dict(plant)
    if not right:
        ways = ["droop", "lag"] + (["rate"] if hidden else [])
        plan.wrong = ways[int(g.integers(len(ways)))]
        droop = "K" if model == "IEEEG1" else "R"
        lag = {"TGOV1": "T3", "IEEEG1": "T5", "GGOV1": "Tb", "HYGOV": "TW"}[model]
        if plan.wrong == "droop":
            plan.record[droop] *= 1.3
        elif plan.wrong == "lag":
            plan.record[lag] *= 2.0
        else:
            plan.record.pop("Uo", None)
            plan.record.pop("Uc", None)
            plan.record.pop("Ropen", None)
    return plan


def structure_files(plan: UnitPlan, folder: Path, experiments: Path) -> list[Path]:
    """The four classic standard structure files (shipped, :mod:`rapid_cosim.structures.shipped`),
    IEEEG1's documenting TG Type I's lead-lag for a TG Type I unit (its record is that IEEEG1);
    for a unit of a stated kind, the shipped files of its kind, not copied."""
    if plan.kind is not None:
        return kind_files(plan.kind)
    out = []
    for name in ("TGOV1", "IEEEG1", "GGOV1", "HYGOV"):
        text = standard_file(name).read_text()
        if name == "IEEEG1" and plan.structure == "TGTypeI":
            text = text.replace('"gov.T1" = 0.001', f'"gov.T1" = {TGTYPEI_DOC["Tc"]}').replace(
                '"gov.T2" = 0.0', f'"gov.T2" = {TGTYPEI_DOC["T3"]}').replace(
                '"gov.T4" = { min = 0.05,', '"gov.T4" = { min = 0.001,')
        path = folder / "structures" / f"{name}.toml"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        out.append(path)
    return out


def simulate_unit(plan: UnitPlan, structures: list[Path], t: np.ndarray, f_dev: np.ndarray, source: ModelSource,
                  governor: dict[str, float] | None = None) -> np.ndarray:
    """The plant's P (pu) on the event: its record model's bench, driven by the true
    frequency (the recorded one is that plus the PMU's noise); with ``governor`` (the
    record on file's values), what that record would have the plant do.

    The plant's inertial power takes the frequency's mean rate over the frame before each
    sample (a backward difference: a real machine does not move before the event), not
    the benches' ROCOF, whose centred local fits reach four frames back across the event
    and would put a precursor into the recorded pre-event window, where the recorder's
    noise is estimated (it did: the P_e units' noise level came out about nine times the
    recorder's, and the bands' noise terms with it)."""
    from ..structures.structure import Structure
    from ..simulator import get_simulator

    structure = next(Structure.load(p) for p in structures if Structure.load(p).name == plan.record_model)
    gov = plan.plant if governor is None else governor
    values = {**structure.fixed, **{f"gov.{k}": v for k, v in gov.items()}, "gov.p_ref": plan.p_ref,
              "f_nom": F_NOM, "mach.H": plan.h}
    sim = get_simulator(source.fmu(structure.input_bench))
    out = "pe" if plan.electrical else "pm"
    rocof = np.concatenate([[0.0], np.diff(f_dev) / np.diff(t)])
    return sim.simulate({k: v for k, v in values.items() if k in sim.parameters}, output_times=t, input_time=t,
                        inputs={"f_dev": f_dev, "rocof": rocof}, outputs=[out])[out]


def write_unit(plan: UnitPlan, folder: Path, seed: int, source: ModelSource, experiments: Path,
               pre_event: float = PRE_EVENT_S) -> Path:
    from ..exchange import FORMATS
    from ..experiment import render_config
    from ..experiment.synthetic import NoiseModel, pmu_noise

    folder.mkdir(parents=True, exist_ok=True)
    # Simulated and noised on the longest span, then cropped: a unit recorded from 10 s
    # before the event carries the same noise as its 30 s recording's last 10 s of them.
    t, f, t_event = event_frequency(experiments, max(pre_event, PRE_EVENT_S))
    recorded = t >= t_event - pre_event - 1e-6
    start = float(t[recorded][0])  # the recording's clock starts at 0 (the benches' simulations do)
    structures = structure_files(plan, folder, experiments)
    p = simulate_unit(plan, structures, t, f - F_NOM, source)
    g = np.random.default_rng([seed, 10_000 + int(plan.name[4:])])
    white = g.uniform(0.0005, 0.001)
    noise = NoiseModel(white_sigma=white, ar1_sigma=white * g.uniform(0.3, 1.0), tau=g.uniform(0.3, 1.0),
                       offset=g.uniform(-0.002, 0.002))
    recorded_p = plan.rating * (p + noise.sample(t.size, g, times=t))
    recorded_f = f + pmu_noise(t.size, rate=30.0, sigma=1e-3, window=0.3, rng=g)
    with open(folder / "data.csv", "w") as fh:
        fh.write("time,FREQ,P\n")
        fh.writelines(f"{a:.4f},{b:.6f},{c:.3f}\n" for a, b, c in zip(t[recorded] - start, recorded_f[recorded],
                                                                       recorded_p[recorded]))
    out = "pe" if plan.electrical else "pm"
    fixed = {"f_nom": F_NOM, "gov.p_ref": round(plan.p_ref, 6), **{f"gov.{k}": v for k, v in TGTYPEI_DOC.items()
                                                                   if k != "T5"}, "gov.pmax": 1.2, "gov.pmin": 0.0}
    if plan.electrical:
        fixed["mach.H"] = round(plan.h, 3)
    config = {"experiment": {"name": plan.name, "model": "iGrGen.TestBenches.FrequencyInput",
                             "description": f"synthetic fleet: {plan.structure} unit on ANDES's tgov1_on frequency"},
              "data": {"file": "data.csv", "time": "time",
                       "outputs": {out: {"column": "P", "unit": "MW", "rating": round(plan.rating, 3)}}},
              "inputs": {"f_dev": {"column": "FREQ", "unit": "Hz", "convert": "deviation", "nominal": F_NOM,
                                   "baseline": "pre-event"}},
              "fixed": fixed,
              "estimate": {"gov.R": {"min": 0.02, "max": 0.12, "label": "R"},
                           "gov.Ts": {"min": 0.1, "max": 5.0, "label": "Ts"},
                           "gov.T5": {"min": 1.0, "max": 20.0, "label": "T5"}},
              "fitness": {"offset": True, "noise": "pre-step", "pre_step_end": round(t_event - start, 4)},
              "simulation": {"output_interval": 0.02, "timeout": 10.0}}
    (folder / "event").mkdir(exist_ok=True)
    shutil.move(str(folder / "data.csv"), folder / "event" / "data.csv")
    (folder / "event" / "config.toml").write_text(render_config(config))
    listed = ("" if plan.kind else "\n[structures]\nfiles = ["
              + ", ".join(f'"structures/{p.name}"' for p in structures) + "]\n")
    (folder / "unit.toml").write_text(f'[unit]\nname = "{plan.name} ({plan.structure})"\n'
                                      + (f'kind = "{plan.kind}"\n' if plan.kind else "")
                                      + f'mva = {plan.rating:.3f}\nbus = {100 + int(plan.name[4:])}\nmachine_id = "1"\n\n'
                                      '[tests]\nconfigs = ["event"]\n' + listed)
    FORMATS["dyr"].write_record(folder / "record.dyr", plan.record_model, _record_values(plan, structures),
                                bus=100 + int(plan.name[4:]), machine_id="1")
    # How far the record on file's own response is from the plant's, noise-free, in the
    # recorder's noise levels (RMS over the longest span, whatever is recorded of it): how
    # wrong the record is for this event.
    off = 0.0 if plan.record_right else float(np.sqrt(np.mean(
        (simulate_unit(plan, structures, t, f - F_NOM, source, plan.record) - p) ** 2)) / noise.sigma)
    truth = {"structure": plan.structure, "plant": plan.plant, "record_right": plan.record_right, "wrong": plan.wrong,
             "record_off_in_noise": off, "hidden_rate": plan.hidden_rate, "electrical": plan.electrical, "H": plan.h,
             "rating": plan.rating}
    (folder / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    return folder


def event_frequency(experiments: Path, pre_event: float = PRE_EVENT_S) -> tuple[np.ndarray, np.ndarray, float]:
    """The event's time and noise-free frequency with ``pre_event`` seconds before the
    event, and the event's time: ANDES's own 10 s, lengthened by holding its initial
    steady state (exact: the grid sits in its power flow's equilibrium until the event)."""
    clean = np.genfromtxt(Path(experiments) / EVENT / "clean.csv", delimiter=",", names=True)
    t, f = clean["time"], clean["FREQ"]
    dt = (t[-1] - t[0]) / (t.size - 1)  # the file's stamps are rounded to 0.1 ms
    extra = int(round((pre_event - ANDES_PRE_EVENT_S) / dt))
    if extra < 0:
        raise ParameterError(f"pre_event {pre_event} s: allowed from ANDES's own {ANDES_PRE_EVENT_S} s up")
    return (np.concatenate([t[0] + dt * np.arange(extra), t + dt * extra]), np.concatenate([np.full(extra, f[0]), f]),
            round(float(t[0] + dt * extra + ANDES_PRE_EVENT_S), 4))


def _record_values(plan: UnitPlan, structures: list[Path]) -> dict[str, float]:
    """The record on file's values: the structure file's documented constants and the
    record's own (wrong or right) values."""
    from ..structures.structure import Structure

    structure = next(Structure.load(p) for p in structures if Structure.load(p).name == plan.record_model)
    fixed = {k.removeprefix("gov."): v for k, v in structure.fixed.items()}
    return {**fixed, **plan.record}


def make_fleet(folder: str | Path, units: int | list[int], *, experiments: str | Path, seed: int = 1,
               source: ModelSource = ModelSource(), name: str | None = None, pre_event: float = PRE_EVENT_S,
               mixed: bool = False) -> Path:
    """Units ``0 .. units - 1`` (or those of a list) under ``folder/units`` and
    ``folder/fleet.toml``; ``experiments`` is the repository's experiments folder (the
    event comes from it: the installed package does not carry it). ``mixed``: the mixed
    fleet's units (module docstring)."""
    folder = Path(folder)
    indices = list(range(units)) if isinstance(units, int) else list(units)
    for k in indices:
        plan = draw_mixed_unit(k, seed) if mixed else draw_unit(k, seed)
        write_unit(plan, folder / "units" / f"unit{k:03d}", seed, source, Path(experiments), pre_event)
    title = name or f"synthetic fleet of {len(indices)} units"
    (folder / "fleet.toml").write_text(f'[fleet]\nname = "{title}"\nunits = ["units/*"]\n')
    return folder / "fleet.toml"

