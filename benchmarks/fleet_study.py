"""The fleet at the benchmark's size (``make bench-fleet``): 100 synthetic units
(:mod:`rapid_cosim.fleet.synthetic`: the four standard structures and TG Type I on one
ANDES event's frequency, a quarter with a binding valve rate, half of the records on file
wrong), run with 1 and with 2 workers on a subset to measure the scaling, and all of them
with 2 workers; then the mixed fleet (``--mixed`` units: TGOV1 with 36 and 60 mHz
deadbands, GAST, IEEEG1, TGOV1; one kind of wrong record leaves the deadband out), with
the droop and band each deadband unit's new record states against its plant's; then the
same recordings cut to their last 10 s before the event (the same noise on what both
hold), their records on file checked only (before and after the longer quiet span).

    python benchmarks/fleet_study.py --units 100 --scaling 10 --mixed 20 --work results/bench-fleet

Prints: the time per unit and in all, the scaling ratio, memory per worker, and against
each unit's truth: wrong records on file flagged (by the bands, or by the noise tests
alone; each miss with how far the wrong record's noise-free response is from the
plant's, in noise levels), right ones passed (each false alarm named with its stated
rate, and the false alarms the stated rates predict), every identified unit's new record
passing its bands, failures.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import threading
import time
from pathlib import Path
from rapid_cosim.fitting.engine import EngineSpec
from rapid_cosim.compiler.source import ModelSource

ROOT = Path(__file__).resolve().parents[1]


class PeakMemory:
    """The largest resident set of any process this one started (the dask workers and
    their nannies), sampled every half second while the block runs."""

    def __init__(self):
        self.peak_mb = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def _sample(self):
        import psutil  # a dependency of dask.distributed

        me = psutil.Process()
        while not self._stop.wait(0.5):
            for child in me.children(recursive=True):
                try:
                    self.peak_mb = max(self.peak_mb, child.memory_info().rss / 2 ** 20)
                except psutil.Error:
                    pass

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def run(folder: Path, units: int | list[int], workers: int, results: Path, *, pre_event: float | None = None,
        check_only: bool = False, mixed: bool = False) -> tuple[dict, float, float]:
    """(the fleet's result, its wall time in s, the largest worker's peak memory in MB);
    ``pre_event``: seconds recorded before the event (default: the synthetic fleet's)."""
    from rapid_cosim.fleet import run_fleet
    from rapid_cosim.fleet.synthetic import PRE_EVENT_S, make_fleet

    spec = make_fleet(folder, units, experiments=ROOT / "experiments", seed=1, source=ModelSource(fmu_dir=ROOT / "fmus"),
                      pre_event=pre_event or PRE_EVENT_S, mixed=mixed)
    if results.exists():
        shutil.rmtree(results)
    t0 = time.perf_counter()
    with PeakMemory() as memory:
        result = run_fleet(spec, results=results, engine=EngineSpec(n_jobs=workers, backend="dask"), source=ModelSource(package=ROOT / "modelica" / "iGrGen", fmu_dir=ROOT / "fmus"), check_only=check_only, log=lambda *_: None)
    return result, time.perf_counter() - t0, memory.peak_mb


def judge(folder: Path, result) -> dict:
    rows = {u.unit: u.to_json() for u in result.units}
    out = {"wrong_flagged": 0, "wrong": 0, "right_passed": 0, "right": 0, "false_alarms": [], "missed": [],
           "new_records_pass": 0, "new_records_within_noise": 0, "identified": 0, "new_records_failing": [],
           "failed": [],
           "right_expected_false_alarms": 0.0, "wrong_by_bands": 0, "wrong_by_noise_only": 0,
           "wrong_flagged_off": [], "wrong_missed_off": [], "right_p": []}
    for name, r in rows.items():
        truth = json.loads((folder / "units" / name / "truth.json").read_text())
        flagged = r["route"] != "record on file passes"
        if r["route"] == "failed":
            out["failed"].append(f"{name}: {r['error']}")
            continue
        on = r["on_file"]
        by_bands = not all(v["passed"] for v in on["tests"].values())
        if truth["record_right"]:
            out["right"] += 1
            out["right_passed"] += not flagged
            out["right_expected_false_alarms"] += on["false_alarm"]
            out["right_p"].append(on["p"])
            if flagged:
                fails = [f"{t}: {', '.join(v['failing'])}" for t, v in on["tests"].items() if not v["passed"]]
                out["false_alarms"].append(f"{name} ({truth['structure']}{', hidden rate' if truth['hidden_rate'] else ''}"
                                           f"): {'; '.join(fails + on['inconsistent'])}; its stated false-alarm "
                                           f"rate {on['false_alarm']:.0%}")
        else:
            out["wrong"] += 1
            out["wrong_flagged"] += flagged
            out["wrong_by_bands"] += by_bands
            out["wrong_by_noise_only"] += flagged and not by_bands
            off = truth["record_off_in_noise"]
            out["wrong_flagged_off" if flagged else "wrong_missed_off"].append(off)
            if not flagged:
                out["missed"].append(f"{name} ({truth['structure']}, {truth['wrong']}: its response "
                                     f"{off:.2f} noise levels RMS from the plant's, noise-free; noise tests p "
                                     f"{on['p']:.2g})")
        if r["route"] == "identified":
            out["identified"] += 1
            back = (r.get("recommended") or {}).get("playback")
            ok = bool(back and all(v["passed"] for v in back["tests"].values()))  # its bands
            out["new_records_pass"] += ok
            out["new_records_within_noise"] += bool(back and not back["inconsistent"])
            if not (ok and back["passed"]):
                out["new_records_failing"].append(f"{name} ({truth['structure']}): {r.get('flags')}")
    return out


def mixed_figures(work: Path, units: int, figures: dict) -> None:
    """The mixed fleet on 2 workers: the same judgement, and per identified unit of each
    family its new record's model, droop and band against its plant's."""
    result, seconds, _ = run(work / "mixed", units, 2, work / "mixed" / "results", mixed=True)
    j = judge(work / "mixed", result)
    found = []
    for u in result.units:
        truth = json.loads((work / "mixed" / "units" / u.unit / "truth.json").read_text())
        if u.route.value != "identified" or not u.recommended:
            continue
        values, plant = u.recommended.parameters, truth["plant"]
        droop = (values["R"] / plant["R"] - 1) if "R" in plant and "R" in values else (
            plant["K"] / values["K"] - 1 if "K" in plant and "K" in values else None)
        band = values.get("db", 0.0) / plant["db"] - 1 if "db" in plant else None
        found.append({"unit": u.unit, "plant": truth["structure"], "wrong": truth["wrong"],
                      "record": u.recommended.fit, "droop_off": droop, "band_off": band, "flags": u.flags})
    figures["mixed"] = {"units": units, "seconds": seconds, **j, "identified_records": found}
    print(f"mixed fleet ({units} units: TGOV1 with 36 and 60 mHz deadbands, GAST, IEEEG1, TGOV1), 2 workers, "
          f"{seconds:.0f} s: wrong records flagged {j['wrong_flagged']}/{j['wrong']}, right ones passed "
          f"{j['right_passed']}/{j['right']} ({j['right_expected_false_alarms']:.1f} false alarms expected), failed "
          f"{len(j['failed'])}" + (f"; missed: {'; '.join(j['missed'])}" if j["missed"] else ""))
    for f in found:
        print(f"  {f['unit']} ({f['plant']}, record on file wrong by its {f['wrong']}): {f['record']}"
              + (f", droop {100 * f['droop_off']:+.1f} %" if f["droop_off"] is not None else "")
              + (f", band {100 * f['band_off']:+.1f} %" if f["band_off"] is not None else "")
              + (f"; flags: {'; '.join(f['flags'])}" if f["flags"] else ""))
    for line in j["false_alarms"]:
        print(f"  flagged although right: {line}")
    for line in j["failed"]:
        print(f"  failed: {line}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--units", type=int, default=100)
    parser.add_argument("--scaling", type=int, default=10, help="units of the 1-worker / 2-worker timing")
    parser.add_argument("--work", type=Path, default=ROOT / "results" / "bench-fleet")
    parser.add_argument("--mixed", type=int, default=20, help="units of the mixed fleet (deadbands, GAST)")
    args = parser.parse_args(argv)
    work = args.work
    figures = {}
    if args.scaling:
        subset = list(range(args.scaling))
        one, t1, _ = run(work / "scaling", subset, 1, work / "scaling" / "results1")
        two, t2, _ = run(work / "scaling", subset, 2, work / "scaling" / "results2")
        same = all({k: v for k, v in a.to_json().items() if k != "seconds"}
                   == {k: v for k, v in b.to_json().items() if k != "seconds"} for a, b in zip(one.units, two.units))
        figures["scaling"] = {"units": len(subset), "one_worker_s": t1, "two_workers_s": t2, "ratio": t1 / t2,
                              "identical": same}
        print(f"{len(subset)} units: 1 worker {t1:.0f} s, 2 workers {t2:.0f} s: {t1 / t2:.2f} times faster; "
              f"results identical: {same}")
    result, seconds, peak_mb = run(work / "fleet", args.units, 2, work / "fleet" / "results")
    j = judge(work / "fleet", result)
    per_unit = [u.seconds for u in result.units]
    passed = [u.seconds for u in result.units if u.route.value == "record on file passes"]
    ident = [u.seconds for u in result.units if u.route.value == "identified"]
    figures["fleet"] = {"units": args.units, "seconds": seconds, "worker_peak_mb": peak_mb, **j,
                        "unit_seconds": {"passing_median": sorted(passed)[len(passed) // 2] if passed else None,
                                         "identified_median": sorted(ident)[len(ident) // 2] if ident else None,
                                         "sum": sum(per_unit)}}
    print(f"{args.units} units on 2 workers: {seconds:.0f} s ({seconds / 60:.1f} min); per unit: a record played back "
          f"{figures['fleet']['unit_seconds']['passing_median'] or 0:.1f} s, an identification "
          f"{figures['fleet']['unit_seconds']['identified_median'] or 0:.0f} s (medians, one worker each); the units' "
          f"own times sum to {sum(per_unit):.0f} s ({sum(per_unit) / seconds:.2f} of 2 workers' wall time); the "
          f"largest worker process peaked at {peak_mb:.0f} MB resident")
    print(f"wrong records flagged: {j['wrong_flagged']}/{j['wrong']} ({j['wrong_by_bands']} by the bands, "
          f"{j['wrong_by_noise_only']} by the noise tests alone)" + (f"; missed: {'; '.join(j['missed'])}"
                                                                  if j["missed"] else ""))
    if j["wrong_flagged_off"]:
        print(f"  the flagged wrong records' responses were {min(j['wrong_flagged_off']):.2f} to "
              f"{max(j['wrong_flagged_off']):.1f} noise levels RMS from the plant's (noise-free)")
    print(f"right records passed: {j['right_passed']}/{j['right']}; false alarms expected from the stated rates: "
          f"{j['right_expected_false_alarms']:.1f}, found: {j['right'] - j['right_passed']}")
    for line in j["false_alarms"]:
        print(f"  flagged although right: {line}")
    print(f"identified units whose new record passes its bands: {j['new_records_pass']}/{j['identified']}; "
          f"not flagged by the playback's noise tests either (lenient on a fitted record: their null fits nothing): "
          f"{j['new_records_within_noise']}/{j['identified']}")
    for line in j["new_records_failing"]:
        print(f"  fails a check: {line}")
    print(f"failed units: {len(j['failed'])}" + "".join(f"\n  {f}" for f in j["failed"]))
    if args.mixed:
        mixed_figures(work, args.mixed, figures)
    # Before and after: the same recordings cut to ANDES's own 10 s before the event, their
    # records on file checked only (nothing identified).
    short, short_s, _ = run(work / "short", args.units, 2, work / "short" / "results", pre_event=10.0, check_only=True)
    k = judge(work / "short", short)
    figures["short_pre_event"] = {"pre_event_s": 10.0, "seconds": short_s, **k}
    for name, f in (("10 s", k), ("30 s", j)):
        print(f"{name} before the event: wrong records flagged {f['wrong_flagged']}/{f['wrong']}, right ones passed "
              f"{f['right_passed']}/{f['right']} ({f['right_expected_false_alarms']:.1f} false alarms expected); the "
              f"right records' noise-test p under 0.05: {sum(p < 0.05 for p in f['right_p'])} "
              f"({0.05 * f['right']:.1f} if calibrated), under 0.2: {sum(p < 0.2 for p in f['right_p'])} "
              f"({0.2 * f['right']:.1f})" + (f"; missed: {'; '.join(f['missed'])}" if f["missed"] else ""))
    (work / "study.json").write_text(json.dumps(figures, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
