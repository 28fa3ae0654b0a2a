"""Performance figures of rapid-cosim (``make bench``). Prints, asserts nothing.

Sections (run all, or name some: ``python benchmarks/run.py simulation pf``):
  simulation  simulations per second on a 60 s staged-test bench: a fresh
              fmpy.simulate_fmu per run against the project's reused simulator
  pf          one particle-filter iteration of 100 particles on staged test 1,
              n_jobs = 1 against 2, and the share of wall time spent outside the simulator
  archive     appending iterations to the HDF5 archive: appendable datasets against
              one group per iteration (time and file size)
"""

from __future__ import annotations

import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BENCH = "iGrGen.TestBenches.StagedTest"


def _fmu(model: str = BENCH) -> Path:
    from rapid_cosim.build import build_models

    return build_models([model], package=ROOT / "modelica" / "iGrGen", fmu_dir=ROOT / "fmus", log=lambda *_: None)[0].fmu


def _rate(fn, n: int) -> float:
    fn(0)  # warm up (library load, first CVode allocation)
    t0 = time.perf_counter()
    for i in range(n):
        fn(i)
    return n / (time.perf_counter() - t0)


def bench_simulation() -> None:
    import fmpy

    from rapid_cosim.simulator import Simulator

    fmu = str(_fmu())
    params = lambda i: {"gov.Ts": 2.0 + 0.01 * i, "gov.R": 0.05, "src.t_step": 10.0}  # noqa: E731
    fresh = _rate(lambda i: fmpy.simulate_fmu(fmu, stop_time=60.0, output_interval=0.05, start_values=params(i),
                                              output=["pm"], record_events=False), 30)
    sim = Simulator(fmu)
    grid = _rate(lambda i: sim.simulate(params(i), stop_time=60.0, output_interval=0.05), 200)
    samples = np.arange(0.0, 60.0, 0.1)
    at_samples = _rate(lambda i: sim.simulate(params(i), output_times=samples), 200)
    print("simulation: 60 s staged-test bench (TG Type I, step at 10 s), CVode rtol 1e-6")
    print(f"  fresh fmpy.simulate_fmu per run, 0.05 s grid  {fresh:8.1f} sim/s  ({1e3 / fresh:.1f} ms)")
    print(f"  reused Simulator, 0.05 s grid (1201 points)   {grid:8.1f} sim/s  ({1e3 / grid:.1f} ms)"
          f"   x{grid / fresh:.1f}")
    print(f"  reused Simulator at 10 Hz samples (600)       {at_samples:8.1f} sim/s  ({1e3 / at_samples:.1f} ms)"
          f"   x{at_samples / fresh:.1f}")


def bench_pf() -> None:
    from rapid_cosim import simulator as simulator_module
    from rapid_cosim.estimators import PFOptions, particle_filter
    from rapid_cosim.evaluate import ProblemObjective
    from rapid_cosim.experiment import build_problem, load_experiment
    from rapid_cosim.simulator import FmuRef

    exp = load_experiment(ROOT / "experiments" / "test1" / "config.toml")
    problem = build_problem([exp])
    refs = {exp.model: FmuRef.from_path(_fmu(exp.model))}
    options = PFOptions(n_particles=100, max_iter=1)
    times = {}
    for n_jobs in (1, 2):
        objective = ProblemObjective(problem, refs, n_jobs=n_jobs)
        objective(problem.space.from_unit(np.full((max(n_jobs, 2), problem.space.dim), 0.5)))  # start workers
        t0 = time.perf_counter()
        particle_filter(objective, problem.space, options=options, rng=np.random.default_rng(0))
        times[n_jobs] = time.perf_counter() - t0

    # share outside the simulator, measured in-process (n_jobs = 1)
    inside = [0.0]
    original = simulator_module.Simulator.simulate

    def timed(self, *args, **kwargs):
        t = time.perf_counter()
        try:
            return original(self, *args, **kwargs)
        finally:
            inside[0] += time.perf_counter() - t

    simulator_module.Simulator.simulate = timed
    try:
        objective = ProblemObjective(problem, refs, n_jobs=1)
        t0 = time.perf_counter()
        particle_filter(objective, problem.space, options=PFOptions(n_particles=100, max_iter=3),
                        rng=np.random.default_rng(0))
        total = time.perf_counter() - t0
    finally:
        simulator_module.Simulator.simulate = original
    print(f"pf: one iteration of 100 particles on staged test 1 ({exp.data.time.size} samples, 90 s)")
    print(f"  n_jobs=1  {times[1]:6.2f} s   ({100 / times[1]:.0f} sim/s)")
    print(f"  n_jobs=2  {times[2]:6.2f} s   ({100 / times[2]:.0f} sim/s)   speed-up x{times[1] / times[2]:.2f}")
    print(f"  3 iterations, n_jobs=1: {total:.2f} s, of which {100 * (1 - inside[0] / total):.1f} % outside "
          f"Simulator.simulate (fitness, estimator, bookkeeping)")


def bench_archive() -> None:
    from rapid_cosim.archive.store import bench_append

    figures = bench_append(n_iter=100, n_particles=100, d=2)
    print("archive: 100 iterations x 100 particles, d = 2")
    for key, value in figures.items():
        print(f"  {key:40s} {value}")


SECTIONS = {"simulation": bench_simulation, "pf": bench_pf, "archive": bench_archive}


def main(argv: list[str]) -> int:
    chosen = argv or list(SECTIONS)
    unknown = [c for c in chosen if c not in SECTIONS]
    if unknown:
        print(f"unknown section(s) {unknown}; choose from {list(SECTIONS)}")
        return 2
    print(f"rapid-cosim benchmarks on {platform.machine()}, Python {platform.python_version()}, "
          f"{__import__('os').cpu_count()} cores\n")
    for name in chosen:
        SECTIONS[name]()
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
