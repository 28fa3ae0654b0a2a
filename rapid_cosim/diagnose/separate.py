"""Which staged test would tell two candidate explanations apart?

Both fitted candidates are simulated on a menu of feasible staged tests (step sizes and
directions, with a return), at the dispatch of the data; the test whose responses differ
most, relative to the noise, is the one to run next.
"""

from __future__ import annotations

import numpy as np

from ..experiment import Experiment
from ..simulator import Simulator, get_simulator
from .candidates import CandidateFit
from .catalogue import CATALOGUE
from .selection import NoiseFloor

STEPS_HZ = (-0.4, -0.2, -0.1, -0.05, 0.05, 0.1, 0.2, 0.4)
HOLD_S = 50.0  # how long each step is held before the return


def _response(sim: Simulator, fit: CandidateFit, template: Experiment, df: float) -> np.ndarray:
    t_step = float(template.fixed.get("src.t_step", 10.0))
    held = {k: v * (template.fixed.get(k, 1.0) if _relative(k) else 1.0) for k, v in fit.spec.held}
    params = {**template.fixed, **held, **fit.parameters,
              "src.df": df, "src.t_step": t_step, "src.t_return": t_step + HOLD_S}
    return sim.simulate(params, stop_time=t_step + 2 * HOLD_S, output_interval=0.1, outputs=["pm"])["pm"]


def _relative(name: str) -> bool:
    return any(e.relative and any(p.name == name for p in e.parameters) for e in CATALOGUE.values())


def separating_test(a: CandidateFit, b: CandidateFit, template: Experiment, noise: NoiseFloor) -> dict:
    """The menu test with the largest RMS difference between ``a`` and ``b`` (in noise units)."""
    # each fit carries the FMU it was calibrated with
    sim_a, sim_b = (get_simulator(f.inputs.fmus[f.model]) for f in (a, b))
    rows = []
    for df in STEPS_HZ:
        d = _response(sim_a, a, template, df) - _response(sim_b, b, template, df)
        d = d - d.mean()  # a constant offset is not evidence: it is profiled out
        rows.append({"df_hz": df, "rms_difference": float(np.sqrt(np.mean(d ** 2))),
                     "rms_over_noise": float(np.sqrt(np.mean(d ** 2)) / noise.sigma)})
    best = max(rows, key=lambda r: r["rms_over_noise"])
    return {
        "between": [a.spec.label, b.spec.label],
        "test": {"df_hz": best["df_hz"], "t_step_s": float(template.fixed.get("src.t_step", 10.0)),
                 "t_return_s": float(template.fixed.get("src.t_step", 10.0)) + HOLD_S,
                 "p_ref": float(template.fixed.get("gov.p_ref", np.nan))},
        "rms_over_noise": best["rms_over_noise"],
        "advice": (f"a staged test with df = {1000 * best['df_hz']:+.0f} mHz, held {HOLD_S:.0f} s and returned, "
                   f"separates {a.spec.label} from {b.spec.label}: their responses differ by "
                   f"{best['rms_over_noise']:.1f} x the noise level (RMS)"),
        "menu": rows,
    }
