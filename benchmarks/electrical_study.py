"""Grid events recorded as electrical power (issue 26): what modelling P_e gains over
treating the recording as mechanical power, per event and over a study.

    python benchmarks/electrical_study.py --show tgov1_on      # make event-electrical: the committed four
    python benchmarks/electrical_study.py --study results/electrical --structures --draws 100  # make bench-electrical

Each event folder is one of ``experiments/electrical/generate.py``'s: ANDES 2.0's GENROU
in the Kundur two-area grid with TGOV1, IEEEG1 or TG Type I (which ANDES has not: run as
the IEEEG1 it equals between its limits, generate.tgtypei_as_ieeeg1), a 200 MW load
switched, recorded as P_e in MW with coloured noise (``data.csv``), and the same noise on
the governor's own output (``mechanical.csv``).

Each event is calibrated (multistart least squares, seed 1, as the tests) three ways:
P_e modelled with H fixed at the documented 6.5 s, P_e modelled with H estimated in 2 to
12 s, and the same recording as if it were P_m (no swing term). The table gives each
estimate's error against the governor ANDES ran, in %: the droop (R, or IEEEG1's K), the
fast lag (TGOV1's T1, IEEEG1's T4, TG Type I's Ts), the slow one (T3, T5) and H.

``--structures``: structure selection (:func:`rapid_cosim.structures.select.select_structure`,
TG Type I, TGOV1 and IEEEG1) on each event's P_e and on its P_m, which should name the same,
and the effect catalogue (:func:`~rapid_cosim.structures.select.effects_on`) with the
true governor on P_e and on P_m, where no effect is hidden: it should name none. Its
verdict "ambiguous" names none either: no effect improves the criterion decisively, but the
data cannot exclude some at a material size (a recorded event is a weaker test than a
staged step).

``--calibration N``: the true governor on each event's P_e with N other noise draws, fitted
and judged as a diagnosis judges its base model (:func:`calibration`): the adequacy
p-values' distribution, the family-wise false alarms, the 90 % intervals' coverage.

``--draws N``: each event again with N other draws of the recorder's noise (:func:`redraws`):
how often R is within 2 % and the time constants within 15 %, per event and for the study.

With ``--study`` and ``--structures`` also generate.py's events with a hidden effect (a
binding valve rate the config does not document; ANDES runs it as IEEEG1's Uo/Uc),
diagnosed on P_e, on P_m and on P_e as if it were P_m (:func:`hidden_effects`): TG Type
I's by the effect catalogue, IEEEG1's by its structure with Uo/Uc optional. It should name
``rate_limit`` on P_e as on P_m, with the plant's rate.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from rapid_cosim.compiler.source import ModelSource

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments" / "electrical"))

KINDS = ("P_e, H fixed", "P_e, H estimated", "as if P_m")
H_BOUNDS = {"min": 2.0, "max": 12.0, "label": "H"}
ROLES = {"TGOV1": ("gov.R", "gov.T1", "gov.T3"), "IEEEG1": ("gov.K", "gov.T4", "gov.T5"),
         "TGTypeI": ("gov.R", "gov.Ts", "gov.T5")}


def variant(folder: Path, kind: str):
    """The event's experiment read three ways (see the module docstring), as the
    mechanical power a staged test would record (``"P_m recorded"``), or its P_e without
    the recorder's noise (``"noise-free"``, clean.csv)."""
    from rapid_cosim.experiment import parse_experiment

    text = (folder / "config.toml").read_text()
    if kind == "P_e, H estimated":
        text = text.replace('"mach.H" = 6.5\n', "").replace(
            "[estimate]\n", '[estimate]\n"mach.H" = { min = 2.0, max = 12.0, label = "H" }\n')
    elif kind == "noise-free":
        text = text.replace('file = "data.csv"', 'file = "clean.csv"')
    elif kind in ("as if P_m", "P_m recorded"):
        text = text.replace("outputs = { pe =", "outputs = { pm =").replace('"mach.H" = 6.5\n', "")
        if kind == "P_m recorded":
            text = text.replace('file = "data.csv"', 'file = "mechanical.csv"')
    return parse_experiment(text, folder / "config.toml")


@functools.cache
def fit(folder: Path, kind: str, fmu_dir: Path = ROOT / "fmus"):
    """The event's calibration read as ``kind`` (made once: show and the table share it)."""
    import rapid_cosim as rc

    return rc.calibrate([variant(folder, kind)], method="ms", seed=1, source=ModelSource(fmu_dir=fmu_dir))


def errors(folder: Path, kind: str, fmu_dir: Path = ROOT / "fmus", fitted=None) -> dict[str, float]:
    """Each estimate's error against the truth, relative (``fitted``: another calibration
    of the event than :func:`fit`'s)."""
    truth = json.loads((folder / "truth.json").read_text())
    fitted = fitted or fit(folder, kind, fmu_dir)
    true = {**{f"gov.{k}": v for k, v in truth["params"].items()}, "mach.H": truth["H"]}
    return {name: x / true[name] - 1 for name, x in zip(fitted.names, fitted.x)}


def redraws(folders: list[Path], draws: int, workdir: Path) -> dict:
    """Each event's P_e (H fixed) again with ``draws`` other draws of the recorder's noise
    on its noise-free samples (clean.csv; generate.recorder_noise, seeds 10000 + k): how
    often the droop is within 2 % and the time constants within 15 %, per event, and so
    how likely a study of these events is to meet both on every one of them."""
    import generate

    import rapid_cosim as rc

    print(f"\n{draws} other noise draws per event (P_e, H fixed): error of the fast lag (mean, sd), share of "
          "draws with the droop within 2 % and with both time constants within 15 %")
    out, p_all = {}, 1.0
    for folder in folders:
        governor = json.loads((folder / "truth.json").read_text())["governor"]
        droop, fast, slow = ROLES[governor]
        clean = np.genfromtxt(folder / "clean.csv", delimiter=",", names=True)
        work = workdir / folder.name
        work.mkdir(parents=True, exist_ok=True)
        (work / "truth.json").write_text((folder / "truth.json").read_text())
        (work / "config.toml").write_text((folder / "config.toml").read_text())
        rows = []
        for k in range(draws):
            f_noise, p_noise = generate.recorder_noise(clean["time"].size, np.random.default_rng(10_000 + k))
            generate.write_data(work / "data.csv", clean["time"], clean["FREQ"] + f_noise, clean["P"] + p_noise)
            fitted = rc.calibrate([variant(work, "P_e, H fixed")], method="ms", seed=1, source=ModelSource(fmu_dir=ROOT / "fmus"))
            rows.append(errors(work, "P_e, H fixed", fitted=fitted))
        e = {name: np.array([r[name] for r in rows]) for name in rows[0]}
        within = float(np.mean((np.abs(e[fast]) < 0.15) & (np.abs(e[slow]) < 0.15)))
        out[folder.name] = {"fast_mean": float(e[fast].mean()), "fast_sd": float(e[fast].std(ddof=1)),
                            "droop_within_2": float(np.mean(np.abs(e[droop]) < 0.02)), "time_within_15": within}
        p_all *= within
        r = out[folder.name]
        print(f"  {folder.name:13s} {governor:7s} fast lag {100 * r['fast_mean']:+5.1f} +- "
              f"{100 * r['fast_sd']:4.1f} %; droop within 2 %: {r['droop_within_2']:.2f}; "
              f"time constants within 15 %: {within:.2f}")
    print(f"  every one of the {len(folders)} recordings has both time constants within 15 % with probability "
          f"{p_all:.2f} (the product)")
    return {"events": out, "all_within": p_all}


def calibration(folders: list[Path], draws: int, workdir: Path, n_jobs: int = 2) -> dict:
    """The true governor on each event's P_e (H documented) with ``draws`` other draws of
    the recorder's noise (clean.csv plus generate.recorder_noise, seeds (20000 + k, the
    event's index): no two events share a draw), fitted
    and judged as a diagnosis fits and judges its base model
    (:mod:`rapid_cosim.diagnose.false_alarms`): the adequacy p-values' distribution, the
    family-wise false alarms and the 90 % intervals' coverage of the plant's values."""
    import generate
    import joblib

    from rapid_cosim.compiler.source import ModelSource
    from rapid_cosim.diagnose.false_alarms import fit_truth, summary, summary_text, to_json
    from rapid_cosim.diagnose.workflow import DiagnoseOptions

    options = DiagnoseOptions(write_model=False)

    def one(folder: Path, k: int):
        truth = json.loads((folder / "truth.json").read_text())
        clean = np.genfromtxt(folder / "clean.csv", delimiter=",", names=True)
        work = workdir / f"{folder.name}-{k}"
        work.mkdir(parents=True, exist_ok=True)
        for name in ("truth.json", "config.toml"):
            (work / name).write_text((folder / name).read_text())
        f_noise, p_noise = generate.recorder_noise(clean["time"].size,
                                                   np.random.default_rng([20_000 + k, folders.index(folder)]))
        generate.write_data(work / "data.csv", clean["time"], clean["FREQ"] + f_noise, clean["P"] + p_noise)
        exp = variant(work, "P_e, H fixed")
        values = {f"gov.{n}": v for n, v in truth["params"].items()}
        return fit_truth(f"{folder.name}-{k}", [exp], [], values, work / "fit", options,
                         ModelSource(ROOT / "modelica" / "iGrGen", ROOT / "fmus"))

    fits = joblib.Parallel(n_jobs=n_jobs)(joblib.delayed(one)(f, k) for k in range(draws) for f in folders)
    s = summary(fits)
    print()
    print(summary_text(f"P_e events ({len(folders)} ANDES events x {draws} noise draws)", s))
    return {"summary": s, "draws": to_json(fits)}


def show(folder: Path) -> None:
    """One calibration in full: the event's P_e with H estimated, and the truth."""
    truth = json.loads((folder / "truth.json").read_text())
    print(f"{folder.name}: {truth['governor']} {truth['params']}, H {truth['H']} s; P_e with H estimated in 2-12 s:")
    print(fit(folder, "P_e, H estimated"))
    print()


def table(folders: list[Path]) -> dict:
    """Print the bias table; return every error."""
    results = {}
    print(f"{len(folders)} ANDES 2.0 events (Kundur two-area, GENROU gen 1, 200 MW load step, P_e in MW with "
          "coloured noise); error of each estimate against the governor ANDES ran, %")
    head = "".join(f" | {k:^27s}" for k in KINDS)
    print(f"{'event':13s} {'gov.':7s}{head}")
    print(f"{'':13s} {'':7s}" + " | droop   fast    slow    H  " * 3)
    for folder in folders:
        governor = json.loads((folder / "truth.json").read_text())["governor"]
        row = results[folder.name] = {kind: errors(folder, kind) for kind in KINDS}
        cells = []
        for kind in KINDS:
            e = row[kind]
            values = [e.get(p) for p in (*ROLES[governor], "mach.H")]
            cells.append(" | " + " ".join("     -" if v is None else f"{100 * v:+6.1f}" for v in values))
        print(f"{folder.name:13s} {governor:7s}" + "".join(cells))
    _summary(results, folders)
    return results


def _summary(results: dict, folders: list[Path]) -> None:
    governors = {f.name: json.loads((f / "truth.json").read_text())["governor"] for f in folders}
    for kind in KINDS:
        role = {r: [abs(results[n][kind][ROLES[governors[n]][i]]) for n in results] for i, r in
                enumerate(("droop", "fast lag", "slow lag"))}
        h = [abs(results[n][kind]["mach.H"]) for n in results if "mach.H" in results[n][kind]]
        print(f"  {kind:17s} largest |error|: " + ", ".join(f"{r} {100 * max(v):.1f} %" for r, v in role.items())
              + (f", H {100 * max(h):.1f} %" if h else "")
              + f"; droop within 2 %: {sum(v < 0.02 for v in role['droop'])}/{len(folders)}, time constants "
              f"within 15 %: {sum(a < 0.15 and b < 0.15 for a, b in zip(role['fast lag'], role['slow lag']))}"
              f"/{len(folders)}")


def structures(folders: list[Path], workdir: Path) -> dict:
    """Structure selection on P_e and on P_m per event (the verdict, the structures within
    the threshold and each one's BIC over the best), and the effect catalogue on P_e with
    the governor ANDES ran, where no effect is hidden."""
    from rapid_cosim.calibration import RunOptions
    from rapid_cosim.diagnose import DiagnoseOptions
    from rapid_cosim.structures.select import effects_on, select_structure

    candidates = candidate_structures()
    out = {}
    print("\nstructure selection (TG Type I, TGOV1, IEEEG1; BIC over the best in brackets) on P_e and on the same "
          "event's P_m, and the effect catalogue on P_e with the true governor")
    for folder in folders:
        governor = json.loads((folder / "truth.json").read_text())["governor"]
        verdicts = {kind: select_structure(candidates, [variant(folder, kind)], workdir=workdir / folder.name / kind[:3],
                                           options=RunOptions(method="ms", seed=1), source=ModelSource(fmu_dir=ROOT / "fmus"),
                                           log=lambda *_: None)
                    for kind in ("P_e, H fixed", "P_m recorded")}
        true = next(c for c in candidates if c.name == governor)
        effects = {kind: effects_on(true, [variant(folder, kind)], [], workdir=workdir / folder.name / f"e{kind[:3]}",
                                    options=DiagnoseOptions(method="ms", seed=1, write_model=False),
                                    source=ModelSource(package=ROOT / "modelica" / "iGrGen", fmu_dir=ROOT / "fmus"), log=lambda *_: None)
                   for kind in ("P_e, H fixed", "P_m recorded")}
        pe, pm = verdicts["P_e, H fixed"], verdicts["P_m recorded"]
        out[folder.name] = {"truth": governor, **{k: {
            "structure": v.structure, "candidates": v.candidates, "delta": {f.name: round(f.delta, 1) for f in v.ranking},
            "effect": e["effect"], "effect_candidates": e["candidates"], "effect_first": e["ranking"][0]["label"]}
            for k, v, e in (("pe", pe, effects["P_e, H fixed"]), ("pm", pm, effects["P_m recorded"]))}}
        same = "same verdict" if pe.structure == pm.structure else (
            "same candidates" if set(pe.candidates) == set(pm.candidates) else "DIFFERENT")
        print(f"  {folder.name:13s} ({governor:7s}) P_e: {_verdict(pe):42s} P_m: {_verdict(pm):42s} {same:15s} "
              f"effects P_e: {_effect(effects['P_e, H fixed'])}; P_m: {_effect(effects['P_m recorded'])}")
    same = sum(v["pe"]["structure"] == v["pm"]["structure"] for v in out.values())
    print(f"  same structure verdict on P_e and P_m: {same}/{len(out)}; an effect named on P_e: "
          f"{sum(_named(v['pe']['effect']) for v in out.values())}/{len(out)}, on P_m: "
          f"{sum(_named(v['pm']['effect']) for v in out.values())}/{len(out)}")
    return out


RATES = {"Uo": "gov.rate_open", "Uc": "gov.rate_close"}  # ANDES's IEEEG1 names, ours (a magnitude)


def hidden_effects(folders: list[Path], workdir: Path, fmu_dir: Path = ROOT / "fmus",
                   kinds: tuple[str, ...] = ("P_e, H fixed", "P_m recorded", "as if P_m")) -> dict:
    """On P_e, P_m and P_e as if P_m, events whose plant has a rate the config does not
    give: TG Type I's by the effect catalogue on it, IEEEG1's by its structure with the
    rates as optional parts (:func:`_optional_rates`). The verdict, whether it fits to the
    noise, and the first-ranked fit's errors against the plant (rate, droop, time
    constants), in %."""
    from rapid_cosim.diagnose import DiagnoseOptions
    from rapid_cosim.structures.select import effects_on

    tg = candidate_structures()[0]
    out = {}
    print("\nhidden effect: the effect catalogue on TG Type I (documented, no rate limit), IEEEG1 with its Uo/Uc "
          "optional, on P_e (H fixed), on P_m, and on P_e as if it were P_m; errors of the first-ranked fit "
          "against the plant, %")
    for folder in folders:
        truth = json.loads((folder / "truth.json").read_text())
        ieeeg1 = truth["governor"] == "IEEEG1"
        true = {**{f"gov.{k}": v for k, v in truth["params"].items()},
                **{f"gov.{k}" if ieeeg1 else RATES[k]: v if ieeeg1 else abs(v) for k, v in truth["hidden"].items()}}
        row = out[folder.name] = {}
        for kind in kinds:
            work = workdir / folder.name / kind[:3]
            d = _optional_rates(folder, kind, work, fmu_dir) if ieeeg1 else effects_on(
                tg, [variant(folder, kind)], [], workdir=work, options=DiagnoseOptions(method="ms", seed=1,
                                                                                      write_model=False),
                source=ModelSource(package=ROOT / "modelica" / "iGrGen", fmu_dir=fmu_dir), log=lambda *_: None)
            first = d["ranking"][0]
            errors = {k: first["parameters"][k] / v - 1 for k, v in true.items() if k in first["parameters"]}
            row[kind] = {"effect": d["effect"], "adequate": d["adequate"], "first": first["label"],
                         "variance_ratio": d["variance_ratio_after"], "errors": errors}
            print(f"  {folder.name:18s} hidden {truth['hidden']}  {kind:12s}: {_effect(d):12s} adequate "
                  f"{d['adequate']!s:5s} (variance ratio {d['variance_ratio_after']:.2f}); {first['label']}: "
                  + ", ".join(f"{k.split('.')[1]} {100 * e:+.1f}" for k, e in errors.items()))
    named = {k: sum(v[k]["effect"] == "rate_limit" for v in out.values()) for k in next(iter(out.values()))}
    print("  rate_limit named: " + ", ".join(f"{k} {n}/{len(out)}" for k, n in named.items()))
    return out


def _optional_rates(folder: Path, kind: str, workdir: Path, fmu_dir: Path) -> dict:
    """IEEEG1 with and without its valve rates free (as ``rapid-cosim identify`` fits a
    structure's optional parts), in :func:`effects_on`'s terms: ``rate_limit`` when the
    rates win by the threshold, else the verdict."""
    from rapid_cosim.calibration import RunOptions
    from rapid_cosim.experiment import EstimateSpec
    from rapid_cosim.structures.select import select_structure

    plain = candidate_structures()[2]
    rates = {"gov.Uo": EstimateSpec("gov.Uo", 0.001, 1.0, "gov.Uo", scale="log"),
             "gov.Uc": EstimateSpec("gov.Uc", -1.0, -0.001, "gov.Uc")}
    plain = replace(plain, fixed={k: v for k, v in plain.fixed.items() if k not in rates}, optional=rates,
                    carries={n: "rate_limit" for n in rates})
    v = select_structure([plain, plain.with_optional()], [variant(folder, kind)], workdir=workdir,
                         options=RunOptions(method="ms", seed=1), source=ModelSource(fmu_dir=fmu_dir), log=lambda *_: None)
    best = v.ranking[0]
    label = {plain.name: "none", plain.with_optional().name: "rate_limit"}
    return {"effect": label.get(v.structure, v.structure), "adequate": best.adequate,
            "variance_ratio_after": best.variance_ratio, "candidates": [label[c] for c in v.candidates],
            "ranking": [{"label": label[f.name], "parameters": f.parameters} for f in v.ranking]}


def _named(effect: str) -> bool:
    return effect not in ("none", "ambiguous", "unexplained")


def _effect(d: dict) -> str:
    """The diagnosis in short: its verdict, the first of its ranking and what it cannot exclude."""
    if d["effect"] == "ambiguous":
        return f"ambiguous, best {d['ranking'][0]['label']}, not excluded {'/'.join(d['candidates'])}"
    return d["effect"]


def _verdict(v) -> str:
    deltas = " ".join(f"{f.name} {f.delta:.0f}" if f.delta else f.name for f in v.ranking)
    return f"{v.structure} [{deltas}]"


def candidate_structures():
    """TG Type I, TGOV1 and IEEEG1 with the constants the events document (generate.py);
    TG Type I's T5 estimated as in its events (the field unit's structure file fixes it at
    6 s, and its pmax at 1.0, which a 200 MW event here exceeds); IEEEG1's K3 the rest of
    the shaft, 1 - K1 (K3_rest: the stages sum to one, as every event's plant's do)."""
    from generate import ESTIMATE, IEEEG1_FIXED, TGOV1_FIXED, TGTYPEI_FIXED

    from rapid_cosim.structures.structure import Structure

    bench = "iGrGen.TestBenches.FrequencyInput"
    tg = Structure.from_tables(
        "TGTypeI", "iGrGen.TestBenches.StagedTest", bench, {f"gov.{k}": v for k, v in TGTYPEI_FIXED.items()},
        {k: {"min": lo, "max": hi} for k, (lo, hi, _) in ESTIMATE["TGTypeI"].items()}, "study")
    tgov1 = Structure.from_tables(
        "TGOV1", f"{bench}TGOV1", f"{bench}TGOV1", {f"gov.{k}": v for k, v in TGOV1_FIXED.items()},
        {"gov.R": {"min": 0.02, "max": 0.12}, "gov.T1": {"min": 0.05, "max": 3.0},
         "gov.T2": {"min": 0.0, "max": 10.0}, "gov.T3": {"min": 3.0, "max": 20.0}}, "study")
    fixed = {**{f"gov.{k}": v for k, v in IEEEG1_FIXED.items()}, "gov.K3_rest": 1.0}
    ieeeg1 = Structure.from_tables(
        "IEEEG1", f"{bench}IEEEG1", f"{bench}IEEEG1", fixed,
        {"gov.K": {"min": 5.0, "max": 50.0}, "gov.T4": {"min": 0.05, "max": 2.0},
         "gov.T5": {"min": 1.0, "max": 20.0}, "gov.K1": {"min": 0.05, "max": 0.6}}, "study")
    return [tg, tgov1, ieeeg1]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("events", nargs="*", type=Path, help="event folders (default: the committed four)")
    parser.add_argument("--study", type=Path, help="write generate.py's study events there (once) and use them")
    parser.add_argument("--structures", action="store_true", help="structure selection and effects too")
    parser.add_argument("--json", type=Path, help="write every figure there")
    parser.add_argument("--show", metavar="EVENT", help="print this event's calibration (H estimated) in full first")
    parser.add_argument("--draws", type=int, default=0, help="each event again with this many other noise draws")
    parser.add_argument("--calibration", type=int, default=0, metavar="N",
                        help="the true governor on each event's P_e with N other noise draws: adequacy p-values, "
                             "family-wise false alarms, the 90 %% intervals' coverage")
    parser.add_argument("--calibration-only", action="store_true", help="run only the calibration study")
    args = parser.parse_args(argv)
    import generate

    hidden = []
    if args.study:
        generate.main(["--study", str(args.study), "--fmus", str(ROOT / "fmus"), *(["--hidden"] * args.structures)])
        folders = [args.study / e.name for e in generate.STUDY]
        hidden = [(args.study / e.name).resolve() for e in generate.HIDDEN] if args.structures else []
    else:
        folders = args.events or [ROOT / "experiments" / "electrical" / e.name for e in generate.EVENTS]
    folders = [f.resolve() for f in folders]
    if args.calibration:
        with tempfile.TemporaryDirectory() as tmp:
            cal = calibration(folders, args.calibration, Path(tmp))
        if args.calibration_only:
            if args.json:
                args.json.write_text(json.dumps({"calibration": cal}, indent=1, default=float) + "\n")
            return 0
    if args.show:
        show(next(f for f in folders if f.name == args.show))
    figures = {"errors": table(folders)}
    if args.calibration:
        figures["calibration"] = cal
    if args.structures:
        with tempfile.TemporaryDirectory() as tmp:
            figures["structures"] = structures(folders, Path(tmp))
            if hidden:
                figures["hidden"] = hidden_effects(hidden, Path(tmp))
    if args.draws:
        with tempfile.TemporaryDirectory() as tmp:
            figures["redraws"] = redraws(folders, args.draws, Path(tmp))
    if args.json:
        args.json.write_text(json.dumps(figures, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
