"""A fit's curves as the validation metrics read them: the archived run's measured and
simulated output on one time base (:class:`~rapid_cosim.validation.metrics.Compared`), and
its metrics. What the metrics are and how they are judged is :mod:`rapid_cosim.validation`'s;
this is only where an archived fit meets them."""

from __future__ import annotations

import numpy as np

from ..validation.metrics import Compared, ValidationMetrics, metrics_of, span
from .archives import FitCurves


def metrics(curves: FitCurves, role: str = "training") -> ValidationMetrics:
    return metrics_of(compared(curves), role, residual=np.asarray(curves.residual, dtype=float))


def compared(curves: FitCurves) -> Compared:
    """The fit's curves as :func:`metrics_of` reads them."""
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

