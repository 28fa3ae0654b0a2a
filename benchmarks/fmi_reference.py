"""The ``reference`` section of ``make bench``: the FMI standard's Reference FMUs
(tests/reference_fmus.py builds them from ../shared/reference-fmus), every one fmpy runs,
both FMI versions and interfaces.

Per FMU, version and interface: the time of one simulation by rapid-cosim (the FMU loaded
once per process, as a calibration's workers hold it; Model Exchange at rtol 1e-10 with the
default runner, Co-Simulation through the C driver), of a fresh ``fmpy.simulate_fmu`` call
on the same grid (what a user without rapid-cosim runs: extract, instantiate, simulate,
free), their ratio, and the largest difference to fmpy's run (Model Exchange: fmpy's CVode
at rtol 1e-10; Co-Simulation: the same communication step) and to the closed form where
there is one. Then memory: 10,000 fresh instantiations of FMI 3.0 BouncingBall in this
process (extracted, loaded, run, freed), resident set growth after a warm-up, and failures.

    python benchmarks/run.py reference
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from timing import best

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

N_FRESH = 10_000


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


def measure_case(path: Path, model: str, interface: str) -> dict:
    """One case's figures (see the module's doc)."""
    import reference_fmus as ref
    from rapid_cosim.simulator import Simulator

    sim = Simulator(path, interface=interface, relative_tolerance=ref.RTOL)
    run = lambda: ref.ours(sim, model, interface)  # noqa: E731
    theirs = ref.fmpy_run(path, model, interface)
    traj = run()
    fig = {"ours_ms": 1e3 * best(run, 20), "fmpy_ms": 1e3 * best(lambda: ref.fmpy_run(path, model, interface), 3),
           "fmpy_diff": ref.largest_difference(traj, theirs, ref.COMPARED_UNTIL.get((model, interface), np.inf))}
    exact = ref.closed_form(model, traj.time)
    if exact is not None and interface == ref.ME:  # Co-Simulation: the FMU's own fixed-step Euler's error
        fig["exact_diff"] = max(float(np.max(np.abs(traj[n] - x) / np.maximum(1.0, np.abs(x))))
                                for n, x in exact.items())
    return fig


def fresh_instantiations(path: Path, n: int = N_FRESH) -> dict:
    """Resident set growth and failures over ``n`` fresh instantiations, after 100."""
    from rapid_cosim.simulator import Simulator

    failures = 0

    def fresh():
        nonlocal failures
        try:
            sim = Simulator(path)
            sim.simulate({}, stop_time=1.0, output_interval=0.1)
            sim.close()
        except Exception:
            failures += 1

    for _ in range(100):
        fresh()
    r0, t0 = _rss_mb(), time.perf_counter()
    for _ in range(n):
        fresh()
    return {"growth_mb": _rss_mb() - r0, "failures": failures, "ms_each": 1e3 * (time.perf_counter() - t0) / n}


def bench_reference(n_fresh: int = N_FRESH) -> None:
    import reference_fmus as ref

    reason = ref.unavailable()
    if reason:
        print(f"reference: skipped, {reason}")
        return
    print("reference: the FMI standard's Reference FMUs, one core; ours: one simulation with the FMU loaded "
          "(ME at rtol 1e-10,")
    print("  CS at fmpy's communication step); fmpy: a fresh simulate_fmu call; difference: largest |ours - fmpy|"
          " (ME: fmpy at rtol 1e-10)")
    print("  and to the closed form (ME; relative where |x| > 1: StateSpace's y grows to 6.6e4)")
    print(f"  {'FMU':22s} {'interface':10s} {'ours':>9s} {'fmpy fresh':>11s} {'x fresh':>8s} {'vs fmpy':>9s} "
          f"{'vs exact':>9s}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fmus = {v: ref.build(v) for v in ref.MODELS}
        for version, model, interface in ref.cases():
            f = measure_case(fmus[version][model], model, interface)
            exact = f"{f['exact_diff']:9.1e}" if "exact_diff" in f else f"{'-':>9s}"
            print(f"  {model + ' ' + version:22s} {'ME' if interface == ref.ME else 'CS':10s} {f['ours_ms']:7.3f}ms "
                  f"{f['fmpy_ms']:9.2f}ms {f['fmpy_ms'] / f['ours_ms']:7.0f}x {f['fmpy_diff']:9.1e} {exact}",
                  flush=True)
        for version, model in ref.REFUSED:
            print(f"  {model + ' ' + version:22s} refused: {ref.REFUSED[version, model]} (fmpy does not run it either)")
        m = fresh_instantiations(fmus["3.0"]["BouncingBall"], n_fresh)
        print(f"  {n_fresh:,} fresh instantiations of BouncingBall 3.0 (ME): {m['ms_each']:.2f} ms each, resident set "
              f"{m['growth_mb']:+.2f} MB, {m['failures']} failures")
