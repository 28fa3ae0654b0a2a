"""Where an identification spends its time, by stage and by kind of work (issue 42):
``make profile-identify``.

    python benchmarks/profile_identify.py [--units steam,electrical,field,fleet] [--json out.json]

Each unit is identified in one process (``n_jobs = 1``, so that every second is seen
here; the report's HTML included, its PDF not), with the functions that make up each
stage and each kind of work wrapped by a timer. A stage is the innermost one running:

- **explanation candidates**: the discrepancy workflow's fits (TG Type I and the effect
  catalogue, then pairs);
- **structure fits**: the standard structures' calibrations (``select_structure``);
- **intervals and identifiability**: Laplace and sandwich intervals, exchanged pairs,
  the Fisher information and the separating step;
- **adequacy null**: the computed null's noise replicates and the adequacy tests on them;
- **held-out playback**: held-out predictions;
- **delivery and report**: the records written and checked, the validation page.

Within each stage the kinds of work: **simulation** (the compiled runner's batches),
**whitening** (residuals whitened by the recorder's noise model), **noise model**
(building whiteners and deviances: REML fits and the null's draws), **Jacobians** (their
simulations counted as the Jacobians', the outermost kind), **data (re)loading** (configs parsed, recordings
read), and **the rest** (the optimisers, archives, bookkeeping). The same unit is then
identified again as ``rapid-cosim identify`` runs it (``n_jobs = 2``, workers in their
own processes) for the wall time against the CPU time of this process and its workers,
and the worker processes' start-up is the gap between the two.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from collections import defaultdict
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
UNITS = {"steam": ROOT / "experiments" / "steam" / "unit.toml",
         "electrical": ROOT / "experiments" / "electrical" / "unit.toml",
         "field": ROOT / "experiments" / "unit.toml",
         "fleet": ROOT / "experiments" / "fleet" / "units" / "unit006"}

STAGES = {  # module path, function (or Class.method) -> stage
    ("rapid_cosim.diagnose.context", "Context.fit_many"): "explanation candidates",
    ("rapid_cosim.structures.select", "select_structure"): "structure fits",
    ("rapid_cosim.diagnose.intervals", "intervals"): "intervals and identifiability",
    ("rapid_cosim.diagnose.intervals", "exchanged"): "intervals and identifiability",
    ("rapid_cosim.structures.identifiability", "identifiability"): "intervals and identifiability",
    ("rapid_cosim.structures.identifiability", "best_separating_step"): "intervals and identifiability",
    ("rapid_cosim.diagnose.null", "replicates_for"): "adequacy null",
    ("rapid_cosim.diagnose.adequacy", "adequacy"): "adequacy null",
    ("rapid_cosim.diagnose.context", "Context.predict"): "held-out playback",
    ("rapid_cosim.calibration.delivery", "deliver_record"): "delivery and report",
    ("rapid_cosim.report.html", "validation_page"): "delivery and report",
}
WORK = {
    ("rapid_cosim.simulator.compiled", "PreparedRun.__call__"): "simulation",
    ("rapid_cosim.noise.whitening", "Whitening.residual"): "whitening",
    ("rapid_cosim.noise.model", "Whitener.__post_init__"): "noise model",
    ("rapid_cosim.noise.estimate", "_deviance"): "noise model",
    ("rapid_cosim.diagnose.candidates", "jacobian_at"): "Jacobians",
    ("rapid_cosim.experiment.config", "parse_experiment"): "data (re)loading",
    ("rapid_cosim.data.readers", "load_measurements"): "data (re)loading",
}


def _workers(rc, n: int) -> dict:
    """identify's keyword for ``n`` workers: ``engine=`` since issue 43, ``n_jobs=`` before
    (``make bench-identify`` runs this file under older revisions too)."""
    import inspect

    if "engine" in inspect.signature(rc.identify).parameters:
        return {"engine": rc.EngineSpec(n_jobs=n)}
    return {"n_jobs": n}


class Clock:
    """Seconds by stage (each stage's own time, its nested stages' left out) and by (stage,
    kind of work): a kind's time goes to the stage running when it started, and to the
    outermost kind (a Jacobian's simulations are the Jacobian's)."""

    def __init__(self):
        self.frames: list[list] = [["other", 0.0]]  # [stage, time spent in nested stages]
        self.kind: list[str] = []
        self.seconds: dict[tuple[str, str], float] = defaultdict(float)
        self.stage_seconds: dict[str, float] = defaultdict(float)

    def wrap_stage(self, name: str, func):
        clock = self

        def wrapped(*args, **kwargs):
            frame = [name, 0.0]
            clock.frames.append(frame)
            t0 = time.perf_counter()
            try:
                return func(*args, **kwargs)
            finally:
                elapsed = time.perf_counter() - t0
                clock.frames.pop()
                clock.stage_seconds[name] += elapsed - frame[1]
                clock.frames[-1][1] += elapsed

        return wrapped

    def wrap_kind(self, name: str, func):
        clock = self

        def wrapped(*args, **kwargs):
            if clock.kind:
                return func(*args, **kwargs)
            clock.kind.append(name)
            stage = clock.frames[-1][0]
            t0 = time.perf_counter()
            try:
                return func(*args, **kwargs)
            finally:
                clock.kind.pop()
                clock.seconds[(stage, name)] += time.perf_counter() - t0

        return wrapped


def _resolve(module: str, attr: str):
    import importlib

    owner = importlib.import_module(module)
    *path, name = attr.split(".")
    for part in path:
        owner = getattr(owner, part)
    return owner, name


@contextmanager
def instrumented(clock: Clock):
    """Every function of STAGES and WORK wrapped, where it is defined and where it was
    imported by name into another module."""
    saved = []
    targets = [(k, v, clock.wrap_stage) for k, v in STAGES.items()] + [(k, v, clock.wrap_kind) for k, v in WORK.items()]
    for (module, attr), label, wrap in targets:
        owner, name = _resolve(module, attr)
        original = getattr(owner, name)
        wrapped = wrap(label, original)
        saved.append((owner, name, original))
        setattr(owner, name, wrapped)
        if "." not in attr:  # imported by name elsewhere: rebind there too
            for mod in list(sys.modules.values()):
                if getattr(mod, "__name__", "").startswith("rapid_cosim") and getattr(mod, name, None) is original:
                    saved.append((mod, name, original))
                    setattr(mod, name, wrapped)
    try:
        yield clock
    finally:
        for owner, name, original in reversed(saved):
            setattr(owner, name, original)


def cpu_seconds() -> float:
    """CPU seconds of this process and every child process, live or ended (psutil: the
    workers of a pool are not reaped, so getrusage would miss them)."""
    import psutil

    me = psutil.Process()
    total = sum(me.cpu_times()[:2])
    for child in me.children(recursive=True):
        try:
            total += sum(child.cpu_times()[:2])
        except psutil.Error:
            continue
    ended = resource.getrusage(resource.RUSAGE_CHILDREN)
    return total + ended.ru_utime + ended.ru_stime


def profile_unit(unit: Path, work: Path) -> dict:
    import rapid_cosim as rc

    clock = Clock()
    t0 = time.perf_counter()
    with instrumented(clock):
        rc.identify(unit, workdir=work / "one", **_workers(rc, 1), report=True, pdf=False, log=lambda *_: None)
    wall_one = time.perf_counter() - t0
    clock.stage_seconds["other"] += wall_one - clock.frames[0][1]
    cpu0 = cpu_seconds()
    t0 = time.perf_counter()
    ident = rc.identify(unit, workdir=work / "two", **_workers(rc, 2), report=True, pdf=False, log=lambda *_: None)
    wall_two = time.perf_counter() - t0
    cpu = cpu_seconds() - cpu0
    table = {}
    for stage, total in clock.stage_seconds.items():
        kinds = {k: s for (st, k), s in clock.seconds.items() if st == stage}
        table[stage] = {"seconds": total, **kinds, "the rest": total - sum(kinds.values())}
    return {"one_process_s": wall_one, "stages": table, "two_workers_s": wall_two, "cpu_s": cpu,
            "simulations": simulations(work / "one"), "answer": answer(ident)}


def simulations(folder: Path) -> int:
    """Every simulation the identification's archives count."""
    from rapid_cosim.archive import RunArchive

    total = 0
    for path in folder.rglob("*.h5"):
        try:
            with RunArchive(path) as view:
                its = view.iterations()
                total += its[-1].n_sims if its else 0
        except Exception:  # a diagnosis record, not a run's archive
            continue
    return total


def answer(ident) -> dict:
    """What an identification answers: the explanation's verdict, the recommended record,
    its fit, estimates and their standard errors."""
    rec = ident.record(ident.recommended) if ident.recommended else None
    e = ident.explanation  # a dict before issue 57 typed it (this file runs under older revisions too)
    return {"explanation": e["verdict"] if isinstance(e, dict) else e.verdict, "recommended": ident.recommended,
            "fit": rec.fit if rec else None, "parameters": rec.parameters if rec else {},
            "se": {k: abs(rec.parameters[k]) * v for k, v in rec.relative_se.items()} if rec else {}}


def text(name: str, r: dict) -> list[str]:
    kinds = ["simulation", "whitening", "noise model", "Jacobians", "data (re)loading", "the rest"]
    out = [f"{name}: {r['one_process_s']:.1f} s in one process; {r['two_workers_s']:.1f} s wall on 2 workers "
           f"with {r['cpu_s']:.1f} s of CPU (this process and its workers)",
           f"  {'stage':<30} {'seconds':>8} " + " ".join(f"{k:>12}" for k in kinds)]
    for stage, row in sorted(r["stages"].items(), key=lambda kv: -kv[1]["seconds"]):
        if row["seconds"] < 0.05:
            continue
        out.append(f"  {stage:<30} {row['seconds']:8.2f} " + " ".join(f"{row.get(k, 0.0):12.2f}" for k in kinds))
    sim = sum(row.get("simulation", 0.0) for row in r["stages"].values())
    out.append(f"  simulation: {sim:.1f} s, {100 * sim / r['one_process_s']:.0f} % of the one-process wall time")
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--units", default=",".join(UNITS))
    parser.add_argument("--work", default="results/profile-identify")
    parser.add_argument("--json")
    args = parser.parse_args(argv)
    results = {}
    for name in args.units.split(","):
        results[name] = profile_unit(UNITS[name], Path(args.work) / name)
        print("\n".join(text(name, results[name])), flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
