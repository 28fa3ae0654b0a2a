"""Make the event1 recording: a synthetic unit riding through an under-frequency event.

The plant is invented for this example, close to the staged tests' unit but not taken
from it: TG Type I with the documented constants of experiments/staged_tests.md (Tc 0.4 s,
T3 0.2 s, T4 1.5 s, T5 6.0 s, limits 0..1 pu) at 60 % of a 400 MW rating, droop
R = 0.055 and governor time constant Ts = 1.6 s. The grid (rapid_cosim.experiment.synthetic.
under_frequency_event) loses 3 % of its generation 20 s into the record: frequency
falls at 0.15 Hz/s to a nadir near -0.24 Hz and recovers to -0.07 Hz.

The recorder is a PMU-fed disturbance recorder at 50 frames per second for 120 s:
frequency with PMU estimator noise (1 mHz RMS, correlated over 0.3 s) and active power
in MW with white plus AR(1) transducer noise (0.3 MW + 0.4 MW RMS) and a 0.8 MW offset,
written as COMTRADE 1999 with binary data (16-bit channels, as recorders store them).

Run from the repository root (``make event1`` does not: the recording is committed)::

    .venv/bin/python experiments/event1/generate.py
"""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from rapid_cosim.compiler import ensure_fmu
from rapid_cosim.data.comtrade import write_comtrade
from rapid_cosim.experiment.synthetic import NoiseModel, synthesize_event

HERE = Path(__file__).resolve().parent
TRUTH = {"gov.R": 0.055, "gov.Ts": 1.6, "gov.p_ref": 0.6, "gov.Tc": 0.4, "gov.T3": 0.2, "gov.T4": 1.5,
         "gov.T5": 6.0, "gov.pmax": 1.0, "gov.pmin": 0.0, "f_nom": 50.0}
RATING_MW = 400.0
SEED = 20240301


def generate(folder: Path = HERE, fmu_dir: str | Path = "fmus", binary: bool = True) -> Path:
    """``folder/event1.cfg`` and ``.dat``; returns the .cfg."""
    fmu = ensure_fmu("iGrGen.TestBenches.FrequencyInput", fmu_dir=fmu_dir)
    rng = np.random.default_rng(SEED)
    noise = NoiseModel(white_sigma=0.3 / RATING_MW, ar1_sigma=0.4 / RATING_MW, phi=0.9, offset=0.8 / RATING_MW)
    t, df, pm = synthesize_event(fmu, TRUTH, duration=120.0, rate=50.0, t_event=20.0, f_noise=1e-3,
                                 p_noise=noise, rng=rng, runner="compiled")  # the committed recording's runner
    return write_comtrade(folder / "event1.cfg", t, {"FREQ": 50.0 + df, "P": pm * RATING_MW},
                          units={"FREQ": "Hz", "P": "MW"}, station="SYNTHETIC-PLANT", device="PMU-DFR",
                          start=datetime(2024, 3, 1, 11, 58, 40, tzinfo=timezone.utc), binary=binary)


if __name__ == "__main__":
    print(generate())
