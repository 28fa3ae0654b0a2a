"""Performance figures (``make bench``): every figure old path against new, in one run.

    python benchmarks/run.py                 # all sections
    python benchmarks/run.py simulation pf   # some of them

Sections:

simulation  one simulation of the base bench at staged test 1's measured samples (90 s,
            900 samples): the Python reference loop, the compiled runner called once per
            set, and the compiled runner over a batch of 200 sets (time per set); then the
            compiled (CVODE) and exponential runners one set per PreparedBatch.run call
            and in batches, with their distance to a tight reference.
input       the FrequencyInput bench driven by a 110 s recorded frequency at 25 Hz:
            fmpy's ``simulate_fmu`` (what models with inputs used before the compiled
            runner), the Python reference loop, and the compiled runner in a batch; then a
            PMU-like record, 120 s at 50 frames/s with irregular time stamps (3 ms of
            jitter) and 1 mHz RMS of noise: the compiled runner (CVODE) against the
            exponential runner, in batches and single calls, with the ratio and each
            one's distance to a tight reference (CVODE at rtol 1e-10).
pf          one particle-filter iteration of 100 particles on staged test 1, one core,
            with each runner; then batches of 100 to 4000 sets on one and two workers.
archive     writing and reading a run's archive.
fmi         every kind of FMU (FMI 2.0 / 3.0 x Model Exchange / Co-Simulation): speed
            against a fresh fmpy.simulate_fmu, accuracy against closed forms, the
            Co-Simulation C driver against its fmpy loop, and memory over 10,000
            simulations and 1,000 instantiations per kind (see fmi_kinds.py).
reference   the FMI standard's Reference FMUs, both versions and interfaces: time per
            simulation (ours, a fresh fmpy.simulate_fmu) and the largest difference to
            fmpy and to closed forms; 10,000 fresh FMI 3.0 instantiations' memory (see
            fmi_reference.py; skipped where ../shared/reference-fmus is absent).
swing       the swing term's cost per simulation (issue 26): one recorded event on the
            TGOV1 bench without the swing term and with it, per runner, single calls and
            batches, the ratio (see swing_cost.py).
whitening   the whitener's band product on a PMU-style recording, 8 to 300 residual
            rows: the pairs of lanes every processor takes against this processor's way
            (AVX-512 where it has them), scipy's CSR product beside them, the numbers
            checked equal (see whitening_bench.py).

Times are the best of a few repeats (the machine may be shared); ratios compare paths
measured in the same run.
"""

from __future__ import annotations

import platform
import sys
import time
from pathlib import Path

import numpy as np

from timing import best

ROOT = Path(__file__).resolve().parents[1]


def _fmu(model: str) -> Path:
    from rapid_cosim.compiler import ensure_fmu

    return ensure_fmu(model, package=ROOT / "modelica" / "iGrGen", fmu_dir=ROOT / "fmus")


def _test1():
    from rapid_cosim.experiment import load_experiment

    return load_experiment(ROOT / "experiments" / "test1" / "config.toml")


def bench_simulation() -> None:
    from rapid_cosim.simulator import Simulator

    exp = _test1()
    sim = Simulator(_fmu(exp.model))
    t = exp.windowed_data().time
    names = ["gov.R", "gov.Ts"]
    values = np.column_stack([np.full(200, 0.05), np.linspace(0.5, 10.0, 200)])

    def loop(runner, n):
        def run():
            for row in values[:n]:
                sim.simulate(dict(zip(names, row)), output_times=t, runner=runner, check=False)
        return run

    python = best(loop("python", 20), 3) / 20
    single = best(loop("compiled", 200), 3) / 200
    prepared = sim.prepare(names, output_times=t, outputs=["pm"])
    batch = best(lambda: prepared.run(values), 5) / len(values)
    print(f"simulation: base bench (TG Type I), staged test 1's {t.size} measured samples over 90 s, one core")
    print(f"  Python reference loop, one set per call   {1e3 * python:8.3f} ms per simulation")
    print(f"  compiled runner, one set per call         {1e3 * single:8.3f} ms   x{python / single:.0f}")
    print(f"  compiled runner, batches of 200 sets      {1e3 * batch:8.3f} ms   x{python / batch:.0f}"
          f"   (target <= 0.15 ms)")
    fixed = {k: v for k, v in exp.fixed.items() if k in sim.parameters}
    names = [*fixed, "gov.R", "gov.Ts"]
    sets = np.column_stack([np.tile(list(fixed.values()), (len(values), 1)), values])
    print(f"  test 1's parameters ({', '.join(f'{k}={v:g}' for k, v in fixed.items())}),"
          " R and Ts varied; one set per PreparedBatch.run call, or batches of 200:")
    _runner_lines(sim, names, sets, dict(output_times=t, outputs=["pm"]), single_target=0.08)


def _runner_lines(sim, names, sets, kw, single_target=None, batch_target=None) -> None:
    """The compiled (CVODE) and exponential runners on the same sets: time per simulation
    one set per call and in one batch, the ratio, and the largest distance of each to a
    tight reference (CVODE at rtol 1e-10) over the first sets. The four timings take
    turns, so that both runners meet the same load on a shared machine."""
    from rapid_cosim.simulator import Simulator

    rows = [sets[i:i + 1] for i in range(min(len(sets), 100))]
    reference = Simulator(sim.path, relative_tolerance=1e-10)  # CVODE: the default runner would compare with itself
    tight = reference.prepare(names, runner="compiled", **kw).run(sets[:10]).values
    prepared = {runner: sim.prepare(names, runner=runner, **kw) for runner in ("compiled", "exponential")}
    calls = {}
    for runner, p in prepared.items():
        calls[runner, "single"] = (lambda p=p: [p.run(r) for r in rows]), len(rows)
        calls[runner, "batch"] = (lambda p=p: p.run(sets)), len(sets)
    best = dict.fromkeys(calls, np.inf)
    for fn, _ in calls.values():
        fn()  # warm up
    for _ in range(5):
        for key, (fn, count) in calls.items():
            t0 = time.perf_counter()
            fn()
            best[key] = min(best[key], (time.perf_counter() - t0) / count)
    figures = {runner: (best[runner, "single"], best[runner, "batch"],
                        np.max(np.abs(p.run(sets[:10]).values - tight))) for runner, p in prepared.items()}
    (s0, b0, e0), (s1, b1, e1) = figures["compiled"], figures["exponential"]
    st = f"   (target <= {single_target} ms)" if single_target else ""
    bt = f"   (target <= {batch_target} ms)" if batch_target else ""
    print(f"    compiled runner (CVODE), one set per call {1e3 * s0:8.3f} ms   batches {1e3 * b0:8.3f} ms"
          f"   max |error| {e0:.1e} pu")
    print(f"    exponential runner, one set per call      {1e3 * s1:8.3f} ms   batches {1e3 * b1:8.3f} ms"
          f"   max |error| {e1:.1e} pu")
    print(f"    ratio (compiled / exponential)            {s0 / s1:8.1f}        batches {b0 / b1:8.1f}")
    print(f"    exponential runner per simulation: one set per call {1e3 * s1:.3f} ms{st}; "
          f"in batches {1e3 * b1:.3f} ms{bt}")


def bench_input() -> None:
    import fmpy
    from scipy.signal import lfilter

    from rapid_cosim.simulator import Simulator

    fmu = _fmu("iGrGen.TestBenches.FrequencyInput")
    rng = np.random.default_rng(0)
    time_ = np.arange(0.0, 110.0, 0.04)  # 25 Hz
    dt = np.clip(time_ - 10.0, 0.0, None)
    event = -0.15 * dt / 4.0 * np.exp(-dt / 8.0)  # Hz: a drop to a nadir and a recovery
    # a PMU's frequency estimate: noise of 1 mHz RMS, correlated over its ~0.3 s window
    a = np.exp(-0.04 / 0.3)
    noisy = event + lfilter([1 - a], [1, -a], 0.004 * rng.standard_normal(time_.size))
    sim = Simulator(fmu)
    instance = fmpy.instantiate_fmu(str(sim.fmu.dir), sim.model_description, fmi_type="ModelExchange")
    values = np.linspace(0.5, 10.0, 100)[:, None]
    print(f"input: FrequencyInput bench driven by a recorded frequency, 110 s at 25 Hz ({time_.size} samples),"
          " power recorded at the same samples")
    for label, f_dev in (("smooth event", event), ("event + PMU noise (1 mHz RMS)", noisy)):
        table = np.zeros(time_.size, dtype=[("time", float), ("f_dev", float)])
        table["time"], table["f_dev"] = time_, f_dev

        def old():  # as the simulator ran models with inputs before the compiled runner
            instance.reset()
            fmpy.simulate_fmu(str(sim.fmu.dir), validate=False, stop_time=110.0, solver="CVode",
                              relative_tolerance=1e-6, output_interval=0.04, record_events=False,
                              start_values={"gov.Ts": 2.0}, input=table, output=["pm"],
                              model_description=sim.model_description, fmu_instance=instance)

        kw = dict(output_times=time_, input_time=time_, inputs={"f_dev": f_dev})
        fresh = best(old, 3)
        python = best(lambda: sim.simulate({"gov.Ts": 2.0}, runner="python", **kw), 3)
        prepared = sim.prepare(["gov.Ts"], outputs=["pm"], **kw)
        batch = best(lambda: prepared.run(values), 5) / len(values)
        print(f"  {label}:")
        print(f"    fmpy.simulate_fmu (the path before)     {1e3 * fresh:8.3f} ms per simulation")
        print(f"    Python reference loop                   {1e3 * python:8.3f} ms   x{fresh / python:.1f}")
        print(f"    compiled runner, batches of 100 sets    {1e3 * batch:8.3f} ms   x{fresh / batch:.0f}"
              f"   (target <= 0.3 ms)")
    bench_recorded_pmu(sim)


def bench_recorded_pmu(sim) -> None:
    """The exponential runner's case: a PMU's record, irregular and noisy."""
    from rapid_cosim.experiment.synthetic import jittered_times, pmu_noise, under_frequency_event

    rng = np.random.default_rng(0)
    t = jittered_times(120.0, 50.0, 0.003, rng)
    event = under_frequency_event(t, t_event=20.0)
    sets = np.column_stack([np.full(100, 0.05), np.linspace(0.5, 10.0, 100)])
    for label, f_dev in (("PMU noise (1 mHz RMS over its 0.3 s window)",
                          event + pmu_noise(t.size, rate=50.0, sigma=1e-3, window=0.3, rng=rng)),
                         ("white noise (1 mHz RMS)", event + 1e-3 * rng.standard_normal(t.size))):
        print(f"  120 s at 50 frames/s ({t.size} samples), time stamps jittered by up to 3 ms, {label},"
              " power at the same samples; R 0.05, Ts 0.5 to 10 s:")
        _runner_lines(sim, ["gov.R", "gov.Ts"], sets,
                      dict(output_times=t, input_time=t, inputs={"f_dev": f_dev}, outputs=["pm"]), batch_target=0.3)


def bench_api() -> None:
    """``rc.simulate`` as a notebook user calls it, against the paths before: a fresh
    ``fmpy.simulate_fmu`` and a simulator built per call (what ``rc.simulate`` did)."""
    import fmpy

    import rapid_cosim as rc
    from rapid_cosim.simulator import Simulator
    from rapid_cosim.experiment.synthetic import jittered_times, pmu_noise, under_frequency_event

    exp = _test1()
    staged = str(_fmu(exp.model))
    grid = dict(stop_time=90.0, output_interval=0.1)
    fresh_fmpy = best(lambda: fmpy.simulate_fmu(staged, stop_time=90.0, output_interval=0.1, solver="CVode",
                                                  start_values={"gov.Ts": 2.0}, output=["pm"]), 3)
    per_call = best(lambda: Simulator(staged).simulate({"gov.Ts": 2.0}, **grid), 3)
    repeated = best(lambda: [rc.simulate(staged, {"gov.Ts": 2.0}, **grid) for _ in range(200)], 3) / 200
    print("rc.simulate, one call per parameter set, one core:")
    print(f"  staged test 1's bench, 90 s at 10 Hz: fresh fmpy.simulate_fmu {1e3 * fresh_fmpy:8.3f} ms; a simulator"
          f" built per call {1e3 * per_call:6.3f} ms; rc.simulate repeated {1e3 * repeated:6.3f} ms"
          f"   x{fresh_fmpy / repeated:.0f} over fmpy, x{per_call / repeated:.0f} over per-call (target <= 0.15 ms)")
    rng = np.random.default_rng(0)
    t = jittered_times(120.0, 50.0, 0.003, rng)
    f_dev = under_frequency_event(t, t_event=20.0) + pmu_noise(t.size, rate=50.0, sigma=1e-3, window=0.3, rng=rng)
    event = str(_fmu("iGrGen.TestBenches.FrequencyInput"))
    table = np.zeros(t.size, dtype=[("time", float), ("f_dev", float)])
    table["time"], table["f_dev"] = t, f_dev
    fresh_fmpy = best(lambda: fmpy.simulate_fmu(event, stop_time=float(t[-1]), output_interval=0.02, solver="CVode",
                                                  start_values={"gov.Ts": 2.0}, input=table, output=["pm"]), 3)
    kw = dict(output_times=t, input_time=t, inputs={"f_dev": f_dev}, outputs=["pm"])
    one = best(lambda: [rc.simulate(event, {"gov.Ts": 2.0}, **kw) for _ in range(20)], 3) / 20
    print(f"  PMU event, 120 s at 50 frames/s ({t.size} samples, jittered, noisy): fresh fmpy.simulate_fmu "
          f"{1e3 * fresh_fmpy:8.3f} ms; rc.simulate {1e3 * one:6.3f} ms   x{fresh_fmpy / one:.0f} (target <= 1 ms)")


def bench_pf() -> None:
    from rapid_cosim.estimators import PFOptions, particle_filter
    from rapid_cosim.fitting.engine import EngineSpec
    from rapid_cosim.fitting.objective import ProblemObjective
    from rapid_cosim.fitting.problem import build_problem
    from rapid_cosim.simulator import FmuRef

    exp = _test1()
    problem = build_problem([exp])
    refs = {exp.model: FmuRef.from_path(_fmu(exp.model))}

    def iteration(objective):
        return lambda: particle_filter(objective, problem.space, options=PFOptions(n_particles=100, max_iter=1),
                                       rng=np.random.default_rng(0))

    one = {runner: best(iteration(ProblemObjective(problem, refs, engine=EngineSpec(1).make(), runner=runner)), 3)
           for runner in ("python", "compiled")}
    print(f"pf: one iteration of 100 particles on staged test 1 ({exp.data.time.size} samples), one core")
    print(f"  Python reference loop                     {1e3 * one['python']:8.1f} ms")
    print(f"  compiled runner                           {1e3 * one['compiled']:8.1f} ms   "
          f"x{one['python'] / one['compiled']:.0f}   (target <= 25 ms)")
    print("  batches over workers (compiled runner; loky processes, started before timing):")
    rng = np.random.default_rng(1)
    objectives = {n: ProblemObjective(problem, refs, engine=EngineSpec(n).make()) for n in (1, 2)}
    for n in (1, 2):
        objectives[n](problem.space.from_unit(rng.uniform(size=(4, 2))))
    for size in (100, 1000, 4000):
        X = problem.space.from_unit(rng.uniform(size=(size, 2)))
        t = {n: best(lambda: objectives[n](X), 2) for n in (1, 2)}
        print(f"    {size:5d} sets: 1 worker {t[1]:6.3f} s, 2 workers {t[2]:6.3f} s   x{t[1] / t[2]:.2f}")


def bench_archive() -> None:
    from archive_bench import bench_append

    figures = bench_append(n_iter=100, n_particles=100, d=2)
    print("archive: 100 iterations x 100 particles, d = 2")
    for key, value in figures.items():
        print(f"  {key:40s} {value}")


def bench_swing() -> None:
    from swing_cost import bench_swing as run

    run()


def bench_whitening() -> None:
    from whitening_bench import bench_whitening as run

    run()


def bench_fmi_kinds() -> None:
    from fmi_kinds import bench_fmi

    bench_fmi()


def bench_reference_fmus() -> None:
    from fmi_reference import bench_reference

    bench_reference()


SECTIONS = {"simulation": bench_simulation, "api": bench_api, "input": bench_input, "pf": bench_pf,
            "archive": bench_archive, "fmi": bench_fmi_kinds, "reference": bench_reference_fmus,
            "swing": bench_swing, "whitening": bench_whitening}


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
    sys.path.insert(0, str(Path(__file__).parent))
    sys.exit(main(sys.argv[1:]))
