"""Which staged test would tell two fitted models apart, their fits held?

Both fitted models (two governor structures) are simulated on a menu of feasible staged
tests (step sizes and directions, with a return), at the dispatch of the data; the test
whose responses differ most, relative to the noise, is the one to run next, if what it
would add to their BIC difference reaches the threshold; otherwise no step separates
them. The diagnosis's advice also counts the refit and the noise (:mod:`.advice`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..experiment import Experiment
from ..simulator import Simulator
from .selection import THRESHOLD, NoiseFloor

STEPS_HZ = (-0.4, -0.2, -0.1, -0.05, 0.05, 0.1, 0.2, 0.4)
HOLD_S = 50.0  # how long each step is held before the return


@dataclass(frozen=True)
class MenuStep:
    """One step of the menu: its size, the two models' RMS difference on it (pu and over
    the noise level) and what it would add to their BIC difference."""

    df_hz: float
    rms_difference: float
    rms_over_noise: float
    evidence: float


@dataclass(frozen=True)
class SeparatingStep:
    """The menu's best step for two fitted models (``between``): the test (its size,
    when it steps and returns, at the data's dispatch), how far apart it puts them and the
    advice in words; ``menu``: every step tried."""

    between: tuple[str, str]
    df_hz: float
    t_step_s: float
    t_return_s: float
    p_ref: float
    rms_over_noise: float
    expected_bic: float
    advice: str
    menu: tuple[MenuStep, ...]

    def to_json(self) -> dict:
        """As structures.json holds it (the test's design under ``test``)."""
        return {"between": list(self.between),
                "test": {"df_hz": self.df_hz, "t_step_s": self.t_step_s, "t_return_s": self.t_return_s,
                         "p_ref": self.p_ref},
                "rms_over_noise": self.rms_over_noise, "expected_bic": self.expected_bic, "advice": self.advice,
                "menu": [asdict(m) for m in self.menu]}


def _response(sim: Simulator, parameters: dict, t_step: float, df: float, dt: float) -> np.ndarray:
    """The response sampled as the recorder would (every ``dt`` s)."""
    params = {**parameters, "src.df": df, "src.t_step": t_step, "src.t_return": t_step + HOLD_S}
    return sim.simulate(params, stop_time=t_step + 2 * HOLD_S, output_interval=dt, outputs=["pm"])["pm"]


def separating_menu(a: tuple[str, Simulator, dict], b: tuple[str, Simulator, dict], template: Experiment,
                    noise: NoiseFloor) -> SeparatingStep:
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
        rms = float(np.sqrt(np.mean((d - d.mean()) ** 2)))
        rows.append(MenuStep(df, rms, rms / noise.sigma, noise.evidence(d)))
    best = max(rows, key=lambda r: r.evidence)
    evidence = best.evidence
    test = f"a staged test with df = {1000 * best.df_hz:+.0f} mHz, held {HOLD_S:.0f} s and returned"
    differ = (f"their responses differ by {best.rms_over_noise:.2f} x the noise level (RMS), worth about "
              f"{evidence:.1f} in BIC")
    advice = (f"{test} separates {label_a} from {label_b}: {differ}" if evidence >= THRESHOLD else
              f"no staged step of the menu separates {label_a} from {label_b} by the threshold: on the "
              f"best, {test}, {differ}; on such tests they are the same model, and the documentation of "
              "the unit must decide")
    return SeparatingStep((label_a, label_b), best.df_hz, t_step, t_step + HOLD_S,
                          float(template.fixed.get("gov.p_ref", np.nan)), best.rms_over_noise, float(evidence),
                          advice, tuple(rows))
