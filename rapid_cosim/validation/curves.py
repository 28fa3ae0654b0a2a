"""A model's curves against a recording, as the validation metrics read them: one
experiment simulated at a parameter set (the fine-grid curve for the eye, the residual
on the measured time base for the figures), and the measured and simulated output on
one time base (:class:`~.metrics.Compared`). Both the validation report (which draws
them) and the fleet's playback of a record on file (which judges them) take them from
here, so that the comparison is made once, below both."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..calibration import RunInputs
from ..fitting.objective import ExperimentResult, evaluate_one, simulate_experiment
from ..simulator import Trajectory
from .metrics import Compared, ValidationMetrics, metrics_of, span


@dataclass(frozen=True)
class FitCurves:
    """One experiment at a parameter set: fine-grid simulation (offset added, so it
    overlays the measurements) and the residuals on the measured time base."""

    detail: ExperimentResult
    fine: Trajectory
    output: str

    @property
    def offset(self) -> float:
        return self.detail.fit.offsets[self.output]

    @property
    def simulated(self) -> np.ndarray:
        return np.asarray(self.fine[self.output]) + self.offset

    @property
    def residual(self) -> np.ndarray:
        return self.detail.fit.residuals[self.output]


def curves_at(inputs: RunInputs, x, i: int) -> FitCurves:
    """Experiment ``i`` of a run's inputs simulated at ``x``."""
    problem = inputs.problem
    exp = problem.experiments[i]
    detail = evaluate_one(problem, inputs.fmus, np.asarray(x, dtype=float), i)
    fine = simulate_experiment(exp, inputs.fmus[exp.model], detail.parameters, fine=True)
    output = next(o for o in exp.outputs if exp.weights[o] > 0)
    return FitCurves(detail, fine, output)


def compared(curves: FitCurves) -> Compared:
    """The curves as :func:`~.metrics.metrics_of` reads them: measured and simulated on
    the measured time base, the masked samples out of both."""
    exp = curves.detail.experiment
    out = curves.output
    t = np.asarray(curves.detail.fit.time, dtype=float)
    r = np.asarray(curves.residual, dtype=float)
    ok = np.isfinite(r)
    measured_all, _ = exp.measured(out)
    idx = np.flatnonzero((exp.data.time >= t[0]) & (exp.data.time <= t[-1]))
    measured = np.where(ok, measured_all[idx], np.nan)
    t0, t_end = span(exp, t)
    noise = None if exp.noise_sigma is None else float(exp.noise_sigma.get(out, np.nan))
    return Compared(exp.name, out, t, measured, measured - r, t0, t_end, noise)


def metrics(curves: FitCurves, role: str = "training") -> ValidationMetrics:
    """The validation metrics of the curves (the residual's RMSE and the response's
    changes and times)."""
    return metrics_of(compared(curves), role, residual=np.asarray(curves.residual, dtype=float))
