"""Which staged test would tell two fitted models apart, their fits held?

Both fitted models (two governor structures) are simulated on a menu of feasible staged
tests (step sizes and directions, with a return), at the dispatch of the data; the test
whose responses differ most, relative to the noise, is the one to run next, if what it
would add to their BIC difference reaches the threshold; otherwise no step separates
them. The diagnosis's advice also counts the refit and the noise (:mod:`.advice`).
"""

from __future__ import annotations

import numpy as np

from ..experiment import Experiment
from ..simulator import Simulator
from .selection import THRESHOLD, NoiseFloor

STEPS_HZ = (-0.4, -0.2, -0.1, -0.05, 0.05, 0.1, 0.2, 0.4)
HOLD_S = 50.0  # how long each step is held before the return


def _response(sim: Simulator, parameters: dict, t_step: float, df: float, dt: float) -> np.ndarray:
    """The response sampled as the recorder would (every ``dt`` s)."""
    params = {**parameters, "src.df": df, "src.t_step": t_step, "src.t_return": t_step + HOLD_S}
    return sim.simulate(params, stop_time=t_step + 2 * HOLD_S, output_interval=dt, outputs=["pm"])["pm"]


def separating_menu(a: tuple[str, Simulator, dict], b: tuple[str, Simulator, dict], template: Experiment,
                    noise: NoiseFloor) -> dict:
    """The menu test with the largest RMS difference between two fitted models, each
    ``(label, simulator, all its parameters)``, stepped when ``template``'s test steps."""
    (label_a, sim_a, par_a), (label_b, sim_b, par_b) = a, b
    t_step = float(template.fixed.get("src.t_step", 10.0))
    rows = []
    for df in STEPS_HZ:
        dt = noise.model.dt
        d = _response(sim_a, par_a, t_step, df, dt) - _response(sim_b, par_b, t_step, df, dt)
        # what the test would add to the BIC difference: the difference whitened by the
        # recorder's noise model, its offset profiled out (an offset is not evidence)
        rows.append({"df_hz": df, "rms_difference": float(np.sqrt(np.mean((d - d.mean()) ** 2))),
                     "rms_over_noise": float(np.sqrt(np.mean((d - d.mean()) ** 2)) / noise.sigma),
                     "evidence": noise.evidence(d)})
    best = max(rows, key=lambda r: r["evidence"])
    evidence = best["evidence"]
    test = f"a staged test with df = {1000 * best['df_hz']:+.0f} mHz, held {HOLD_S:.0f} s and returned"
    differ = (f"their responses differ by {best['rms_over_noise']:.2f} x the noise level (RMS), worth about "
              f"{evidence:.1f} in BIC")
    return {
        "between": [label_a, label_b],
        "test": {"df_hz": best["df_hz"], "t_step_s": t_step, "t_return_s": t_step + HOLD_S,
                 "p_ref": float(template.fixed.get("gov.p_ref", np.nan))},
        "rms_over_noise": best["rms_over_noise"],
        "expected_bic": float(evidence),
        "advice": (f"{test} separates {label_a} from {label_b}: {differ}" if evidence >= THRESHOLD else
                   f"no staged step of the menu separates {label_a} from {label_b} by the threshold: on the "
                   f"best, {test}, {differ}; on such tests they are the same model, and the documentation of "
                   "the unit must decide"),
        "menu": rows,
    }
