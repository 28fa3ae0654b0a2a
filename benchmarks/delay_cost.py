"""What the exact transport delay costs (issue 55): the discrepancy workflow's
recorded-frequency bench with a delay against the same bench with a measurement lag (one
state more, no per-set input), 40 parameter sets on event1's 6000-row PMU recording, on
both compiled runners. A delayed bench's sets each get the recording moved by their own
delay (``rapid_cosim.simulator.delayed``), so each is prepared and run alone.

    python benchmarks/delay_cost.py

Prints ms per set for each and the ratio (both in one run: the machine's noise cancels).
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    from rapid_cosim.compiler import build_models
    from rapid_cosim.diagnose.catalogue import INPUT_BENCH, write_bench
    from rapid_cosim.experiment import load_experiment
    from rapid_cosim.simulator import Simulator

    benches = {"delay": ("FrequencyInputDelay", "dly.T"), "measurement_lag": ("FrequencyInputMeasurementLag", "meas.T")}
    with tempfile.TemporaryDirectory() as tmp:
        package = Path(tmp) / "iGrGen"
        shutil.copytree(ROOT / "modelica" / "iGrGen", package)
        for effect, (name, _) in benches.items():
            write_bench(package, [effect], f"iGrGen.Diagnosed.{name}", base=INPUT_BENCH, values={"f_nom": 50.0})
        built = build_models([f"iGrGen.Diagnosed.{n}" for n, _ in benches.values()], package=package,
                             fmu_dir=Path(tmp) / "fmus", log=lambda *_: None)
        fmus = {o.model.rsplit(".", 1)[1]: o.fmu for o in built}
        table = load_experiment(ROOT / "experiments" / "event1" / "config.toml").input_table
        times = np.arange(0.0, 120.0, 0.02)
        rng = np.random.default_rng(0)
        for runner in ("exponential", "compiled"):
            per_set = {}
            for effect, (name, parameter) in benches.items():
                values = np.column_stack([rng.uniform(0.3, 2.0, 40), rng.uniform(0.1, 1.5, 40)])
                batch = Simulator(fmus[name]).prepare(["gov.Ts", parameter], output_times=times, inputs=table,
                                                      outputs=["pm"], runner=runner)
                batch.run(values[:2])
                start = time.perf_counter()
                batch.run(values)
                per_set[effect] = (time.perf_counter() - start) / len(values)
            print(f"{runner} runner: delay {1e3 * per_set['delay']:.1f} ms per set, measurement lag "
                  f"{1e3 * per_set['measurement_lag']:.1f} ms: {per_set['delay'] / per_set['measurement_lag']:.2f} "
                  "times")
    return 0


if __name__ == "__main__":
    sys.exit(main())
