"""Where a diagnosis spends its time (``make bench-speed``).

For the workloads users wait on: the field campaign of ``make diagnose`` (tests 1-3,
5-7, 9, 10; 4 and 8 held out), a four-test staged campaign, one recorded event and three
(120 s at 50 frames/s, PMU noise; the synthetic ones with rate limits hidden: the study's plants,
:mod:`rapid_cosim.diagnose.campaigns`), it prints the wall time on two workers and, from a
run in one process, the number of simulations, the time per simulation and the share of
the time spent outside the simulator. On the four-test campaign it also runs the
earlier way of searching (PF10+NM and a PSO10+NM+scan+NM second search per candidate,
CVODE), so that before and after come from one run on one machine.

Counting: the runner's batch calls of the process are timed (``PreparedBatch.run``
wrapped here); worker processes are not counted, hence the one-process run.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from rapid_cosim.compiler.source import ModelSource
from rapid_cosim.fitting.engine import EngineSpec

ROOT = Path(__file__).resolve().parents[1]


class Counter:
    """Simulations and seconds inside the runner, over this process."""

    def __init__(self):
        from rapid_cosim.simulator import simulation

        self.sets, self.calls, self.seconds = 0, 0, 0.0
        original = simulation.PreparedBatch.run

        def run(batch, values, check=False):
            t0 = time.perf_counter()
            out = original(batch, values, check)
            self.seconds += time.perf_counter() - t0
            self.sets += out.values.shape[0]
            self.calls += 1
            return out

        simulation.PreparedBatch.run = run


def _campaign(kind: str, work: Path):
    from rapid_cosim.compiler import build_models
    from rapid_cosim.diagnose.campaigns import draw_case, write_campaign
    from rapid_cosim.diagnose.catalogue import BASE_BENCH, EFFECTS
    from rapid_cosim.experiment import load_experiment

    package = work / "package" / "iGrGen"
    if not package.exists():
        shutil.copytree(ROOT / "modelica" / "iGrGen", package)
        build_models(list(dict.fromkeys([BASE_BENCH, *(e.bench for e in EFFECTS.values())])), package=package,
                     fmu_dir=work / "fmus", log=lambda *_: None)
    source = ModelSource(package, work / "fmus")
    case = draw_case("rate_limit", 1, source=source, kind=kind)
    configs = write_campaign(case, work / kind, source=source)
    exps = [load_experiment(c) for c in configs]
    return exps[:-1], exps[-1:], package, work / "fmus"


def _field():
    from rapid_cosim.experiment import load_experiment

    names = ["test1", "test2", "test3", "test5", "test6", "test7", "test9", "test10"]
    return ([load_experiment(ROOT / "experiments" / n) for n in names],
            [load_experiment(ROOT / "experiments" / n) for n in ("test4", "test8")],
            ROOT / "modelica" / "iGrGen", ROOT / "fmus")


def measure(label: str, workload, options, counter: Counter, work: Path) -> None:
    from rapid_cosim.diagnose.workflow import diagnose

    training, heldout, package, fmu_dir = workload
    rows = []
    for n_jobs in (1, 2):
        before = (counter.sets, counter.seconds)
        folder = work / f"{label}-{n_jobs}"
        shutil.rmtree(folder, ignore_errors=True)
        t0 = time.perf_counter()
        d = diagnose(training, heldout, workdir=folder, options=replace(options, engine=EngineSpec(n_jobs)), source=ModelSource(package=package, fmu_dir=fmu_dir), log=lambda *_: None)
        rows.append((time.perf_counter() - t0, counter.sets - before[0], counter.seconds - before[1], d))
    (wall1, sets, seconds, d), (wall2, *_rest) = rows
    tests = len(training) + len(heldout)
    print(f"{label}: {d.named.verdict} (adequate: {d.adequate})")
    print(f"  wall time {wall2:6.1f} s on 2 workers, {wall1:6.1f} s in one process")
    print(f"  {sets} parameter sets simulated ({sets / max(tests, 1):.0f} per test over {tests} tests)"
          f" = {1e3 * seconds / max(sets, 1):.3f} ms per set; outside the simulator {1 - seconds / wall1:.0%}"
          " of the one-process time")


def main(argv: list[str]) -> int:
    from rapid_cosim.diagnose.workflow import DiagnoseOptions

    work = Path(tempfile.mkdtemp(prefix="rapid_cosim_speed_"))
    counter = Counter()
    options = DiagnoseOptions(write_model=False)
    try:
        print("diagnosis time, 2 cores (first: a process's first diagnosis loads libraries and FMUs)")
        staged = _campaign("staged", work)
        measure("four-test staged campaign (3 training, 1 held out)", staged, options, counter, work)
        earlier = replace(options, method="pf:10+nm", searches=("pso:10+nm+scan+nm",), runner="compiled",
                          estimator_options={"pf": {"n_particles": 40}, "nm": {"xatol": 1e-4, "fatol": 1e-10}})
        measure("  the same, searched the earlier way (PF10+NM and PSO10+NM+scan+NM, CVODE)", staged, earlier,
                counter, work)
        events = _campaign("event", work)
        measure("one recorded event, 120 s at 50 frames/s", (events[0][:1], [], *events[2:]), options, counter, work)
        measure("three recorded events, 120 s at 50 frames/s (2 training, 1 held out)", events, options, counter,
                work)
        measure("field campaign (make diagnose: 8 training tests, 2 held out)", _field(), options, counter, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
