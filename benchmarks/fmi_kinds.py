"""The ``fmi`` section of ``make bench``: every kind of FMU (FMI 2.0 / 3.0 x Model Exchange
/ Co-Simulation), built from the conformance suite's C models (``tests/fmus``).

Per kind:

- speed: the droop plant twin over 60 s, 601 output samples, a measured input with two
  steps; one ``rc.simulate`` call (the FMU loaded once per process, as a calibration's
  workers do), the same set in batches of 200 (time per set), and a fresh
  ``fmpy.simulate_fmu`` call on the same grid and input (what a user without rapid-cosim
  runs: fmpy extracts, instantiates and frees the FMU every call), with the ratio;
- accuracy: the largest distance of the droop twin to its closed form, and of the bouncing
  ball (state events) to its analytic parabolas, 4 s at 1 ms;
- for Co-Simulation, the C driver against the fmpy loop it is checked against (runner
  "python"): why the driver is in C;
- memory: 10,000 ``rc.simulate`` calls and 1,000 fresh instantiations (FMU extracted,
  loaded, run once, freed) in this process, resident set growth after a warm-up
  (target < 50 MB per kind).

    python benchmarks/run.py fmi
"""

from __future__ import annotations

import os
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

from timing import best

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

N_SIMS, N_FRESH = 10_000, 1_000
R, T, P_REF = 0.05, 2.0, 0.6
STEPS = dict(input_time=np.array([0.0, 1.0, 1.0, 30.0, 30.0, 60.0]),
             inputs={"dw": np.array([0.0, 0.0, 0.01, 0.01, -0.005, -0.005])})


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


def _droop_exact(t):
    return (P_REF - 0.01 / R * (1 - np.exp(-(t - 1).clip(0) / T))
            + 0.015 / R * (1 - np.exp(-(t - 30).clip(0) / T)))


def _ball_exact(t, g=9.81, e=0.7, h0=1.0):
    bounce, v = [np.sqrt(2 * h0 / g)], [g * np.sqrt(2 * h0 / g)]
    while e * v[-1] >= 0.1:
        v.append(e * v[-1])
        bounce.append(bounce[-1] + 2 * v[-1] / g)
    k = np.searchsorted(bounce, t, side="right") - 1
    s = t - np.asarray(bounce)[np.maximum(k, 0)]
    speed = np.asarray(v + [0.0])[np.minimum(k + 1, len(v))]
    h = np.where(k < 0, h0 - 0.5 * g * t ** 2, speed * s - 0.5 * g * s ** 2)
    return np.where(k == len(bounce) - 1, 0.0, h)


def measure_kind(kind: str, folder: Path, memory: bool = True) -> dict:
    """The figures of one kind (see the module's doc)."""
    import fmpy

    import rapid_cosim as rc
    from c_fmus import build_kind
    from rapid_cosim.simulator import Simulator

    droop = build_kind("DroopPlant", folder, kind)
    ball = build_kind("BouncingBall", folder, kind)
    t = np.linspace(0.0, 60.0, 601)
    one = lambda: rc.simulate(droop, {"R": R}, output_times=t, **STEPS)  # noqa: E731
    fig = {"single_ms": 1e3 * best(one, 20)}
    sim = Simulator(droop)
    prepared = sim.prepare(["R"], output_times=t, input_time=STEPS["input_time"], inputs=STEPS["inputs"])
    values = np.full((200, 1), R)
    fig["batch_ms"] = 1e3 * best(lambda: prepared.run(values), 3) / 200
    signal = np.array(list(zip(STEPS["input_time"], STEPS["inputs"]["dw"])), dtype=[("time", float), ("dw", float)])
    fresh_fmpy = lambda: fmpy.simulate_fmu(str(droop), stop_time=60.0, output_interval=0.1,  # noqa: E731
                                           input=signal, start_values={"R": R})
    fig["fmpy_ms"] = 1e3 * best(fresh_fmpy, 3)
    fig["droop_error"] = float(np.max(np.abs(one()["p"] - _droop_exact(t))))
    tb = np.linspace(0.0, 4.0, 4001)
    fig["ball_error"] = float(np.max(np.abs(Simulator(ball).simulate({}, output_times=tb)["h"] - _ball_exact(tb))))
    if sim.fmu.co_simulation:
        loop = sim.prepare(["R"], output_times=t, runner="python", input_time=STEPS["input_time"],
                           inputs=STEPS["inputs"])
        fig["loop_ms"] = 1e3 * best(lambda: loop.run(values[:10]), 3) / 10
    if memory:
        fig.update(memory_growth(droop))
    return fig


def memory_growth(fmu: Path, n_sims: int = N_SIMS, n_fresh: int = N_FRESH) -> dict:
    """Resident set growth over ``n_sims`` rc.simulate calls and ``n_fresh`` fresh
    instantiations, after a warm-up of 200 and 20."""
    import rapid_cosim as rc
    from rapid_cosim.simulator import Simulator

    grid = dict(stop_time=60.0, output_interval=0.1, **STEPS)

    def fresh():
        s = Simulator(fmu)
        s.simulate({"R": R}, **grid)
        s.close()
        s.fmu.close()

    for i in range(200):
        rc.simulate(fmu, {"R": R + 1e-7 * i}, **grid)
    for _ in range(20):
        fresh()
    r0 = _rss_mb()
    for i in range(n_sims):
        rc.simulate(fmu, {"R": R + 1e-7 * i}, **grid)
    r1 = _rss_mb()
    for _ in range(n_fresh):
        fresh()
    r2 = _rss_mb()
    return {"sims_mb": r1 - r0, "fresh_mb": r2 - r1, "total_mb": r2 - r0}


def bench_fmi() -> None:
    from c_fmus import KINDS

    names = {"me2": "FMI 2.0 ME", "cs2": "FMI 2.0 CS", "me3": "FMI 3.0 ME", "cs3": "FMI 3.0 CS"}
    print("fmi: the conformance suite's droop plant twin, 60 s, 601 samples, an input with two steps, one core;")
    print("  fresh fmpy.simulate_fmu on the same grid and input; errors against closed forms;")
    print(f"  memory: {N_SIMS:,} rc.simulate calls + {N_FRESH:,} fresh instantiations per kind (target < 50 MB)")
    header = (f"  {'kind':11s} {'rc.simulate':>11s} {'batch/set':>10s} {'fmpy fresh':>11s} {'x fresh':>8s} "
              f"{'droop err':>10s} {'ball err':>9s} {'fmpy loop':>10s} {'mem MB':>7s}")
    print(header)
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for kind in KINDS:
            f = measure_kind(kind, Path(tmp))
            loop = f"{f['loop_ms']:8.3f}ms" if "loop_ms" in f else f"{'-':>10s}"
            print(f"  {names[kind]:11s} {f['single_ms']:9.3f}ms {f['batch_ms']:8.3f}ms {f['fmpy_ms']:9.2f}ms "
                  f"{f['fmpy_ms'] / f['single_ms']:7.0f}x {f['droop_error']:10.1e} {f['ball_error']:9.1e} {loop} "
                  f"{f['total_mb']:7.2f}", flush=True)
