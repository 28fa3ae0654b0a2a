"""The calibrated parameters' intervals: Laplace's approximation of the whitened Gaussian
likelihood, widened where the whitened residual is still correlated.

Why widen: the likelihood is the noise model's. Where that model is estimated from a few
seconds of quiet data (10 s before a grid event), it can be off (a slow component's
correlation time a third of the recorder's), and the residual it whitens is then not
white; the likelihood's curvature overstates what the data say, and on ANDES events the
true governor fell outside the 90 % intervals in a quarter of the noise draws. The
sandwich ``A^-1 B A^-1``, with ``A = J'J`` the information of the whitened residual and
``B`` the long-run covariance of its scores ``J_t e_t`` (Newey and West, Econometrica 55
(1987) 703, Bartlett weights over ``ceil(n^(1/3))`` lags), is the covariance whatever
correlation the whitening left; where it left none, it is the likelihood's. Each
interval is the wider of the two.

Two lags in series that the tests fit either way round (:func:`.identifiability.exchanges`:
TG Type I's Ts and T5 with T5 free) have two optima: :func:`exchanged` gives each one's
interval at the other optimum (the swapped pair's intervals), reported beside it. On the
ANDES event tgtypei_off_b, some noise draws put Ts at the reheater's 4.5 s: the truth then
lies in that other interval.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from ..calibration import log_likelihood_for
from ..fitting.engine import EngineSpec
from ..errors import RapidCosimError
from ..estimators.laplace import laplace
from ..fitting.objective import ProblemObjective
from .candidates import CandidateFit, experiment_blocks
from .exchanges import exchanges

LEVEL = 0.9
STEP = 1e-3  # forward difference in unit coordinates


def intervals(fit: CandidateFit, level: float = LEVEL, engine: EngineSpec = EngineSpec(), log=lambda *_: None) -> dict[str, list[float]]:
    """Symmetric ``level`` intervals of ``fit``'s estimates (module docstring); {} where
    the problem has no likelihood."""
    problem = fit.inputs.problem
    log_likelihood = log_likelihood_for(problem)
    if log_likelihood is None:
        return {}
    objective = ProblemObjective(problem, fit.inputs.fmus, engine=engine.make())
    x = np.array([fit.parameters[n] for n in problem.names])
    try:
        approx = laplace(lambda X: -log_likelihood(objective(X)), problem.space, x, level=level)
    except RapidCosimError as e:  # intervals are evidence, not the verdict: report, do not fail
        log(f"  no parameter intervals: {e}")
        return {}
    half = np.where(np.isfinite(approx.interval[:, 1]), approx.interval[:, 1] - approx.mean, np.inf)
    robust = sandwich_half_widths(fit, x, level)
    if robust is not None:
        half = np.maximum(half, robust)
    return {name: [float(x[k] - half[k]), float(x[k] + half[k])] for k, name in enumerate(problem.names)}


def exchanged(fit: CandidateFit, bands: dict[str, list[float]], noise) -> dict[str, list[float]]:
    """For parameters the tests fit either way round with another, the interval at the
    other optimum: the partner's (module docstring)."""
    if not bands or fit.inputs is None:
        return {}
    names = fit.inputs.problem.names
    x = np.array([fit.parameters[n] for n in names])
    out = {}
    for a, b, _ in exchanges(fit.inputs, x, noise):
        if a in bands and b in bands:
            out[a], out[b] = list(bands[b]), list(bands[a])
    return out


def sandwich_half_widths(fit: CandidateFit, x: np.ndarray, level: float = LEVEL) -> np.ndarray | None:
    """Half-widths of the ``level`` intervals from the Newey-West sandwich (natural units),
    or None where the whitened residuals are not at hand."""
    problem = fit.inputs.problem
    space = problem.space
    X, steps = space.stepped(np.clip(space.to_unit(x), 0.0, 1.0), STEP)
    _, R = ProblemObjective(problem, fit.inputs.fmus).residuals(X)
    if not np.all(np.isfinite(R)):
        return None
    J = (R[1:] - R[0]).T / steps  # (samples, parameters) in unit coordinates
    A = np.zeros((space.dim, space.dim))
    B = np.zeros_like(A)
    for e, block in experiment_blocks(problem):
        whitened = fit.tests[e.name].whitened if e.name in fit.tests else None
        if whitened is None:
            return None
        w = whitened[np.isfinite(whitened)]
        r0 = R[0, block]
        if w.size != r0.size or not np.any(r0):
            return None
        c = math.sqrt(float(w @ w) / float(r0 @ r0))  # the objective's rows are the whitened residual scaled
        Je, res = c * J[block], c * r0
        A += Je.T @ Je
        scores = Je * res[:, None]
        B += newey_west(scores)
    try:
        A_inv = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return None
    cov_u = A_inv @ B @ A_inv
    se_u = np.sqrt(np.clip(np.diag(cov_u), 0.0, None))
    dxdu = (X[1:][np.arange(space.dim), np.arange(space.dim)] - X[0]) / steps
    return stats.norm.ppf(0.5 + level / 2) * se_u * np.abs(dxdu)


def newey_west(scores: np.ndarray, lags: int | None = None) -> np.ndarray:
    """The long-run covariance of ``scores`` (samples, parameters), Bartlett weights."""
    n = scores.shape[0]
    lags = int(math.ceil(n ** (1 / 3))) if lags is None else lags
    out = scores.T @ scores
    for k in range(1, min(lags, n - 1) + 1):
        g = scores[k:].T @ scores[:-k]
        out += (1 - k / (lags + 1)) * (g + g.T)
    return out
