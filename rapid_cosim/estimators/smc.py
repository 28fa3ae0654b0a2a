"""Sequential Monte Carlo sampler with adaptive likelihood tempering: the Bayesian
counterpart of the particle filter, returning a posterior rather than a best point.

The targets are ``pi_lam(x) ~ prior(x) L(x)^lam`` for temperatures 0 = lam_0 < ... = 1,
with the prior uniform in the bounds. Per stage:

1. **Temperature.** The next lam is found by bisection so that the conditional ESS of
   the incremental weights ``L^(lam' - lam)`` (Zhou, Johansen & Aston 2016; it is the
   plain ESS of the incremental weights when the cloud is equally weighted) is
   ``ess_target`` times its value for an infinitesimal step, i.e. ``ess_target * N``
   unless some particles have zero likelihood.
2. **Reweight**, accumulating the log-evidence ``log Z = sum log sum_i W_i w_i`` (Z is
   the marginal likelihood under the uniform prior density on the box).
3. **Resample** (systematic) when the ESS of the weights falls below
   ``resample_threshold * N``.
4. **Move** with ``n_mcmc_steps`` random-walk Metropolis steps, proposal covariance
   ``proposal_scale`` (default 2.38^2/d, Roberts & Rosenthal 2001) times the weighted
   covariance of the cloud in unit coordinates, fixed within the stage. Proposals outside
   the box have prior 0 and are rejected without simulation; all others of one step are
   scored in ONE objective call.

After lam = 1 is reached and moved, ``n_final_steps`` extra steps may decorrelate the
cloud further. ``log_likelihood(evals)`` comes from the caller (the noise model lives
with the fitness), so the sampler stays generic; failed simulations and non-finite
log-likelihoods get log-likelihood -inf (zero posterior mass).

``x0`` is accepted for the common signature (chains pass it) but ignored: the sampler is
only exact when it starts from the prior. One :class:`Iteration` = one objective call:
the prior sample, then every MCMC step; ``x``/``fitness`` hold the cloud after the step,
``extras`` the temperature, acceptance, ESS, evidence so far and the proposals.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .uncertainty import Uncertainty
from .base import (Evaluations, EstimationResult, IterationCallback, Objective,
                   SearchSpace, Tracker, check_option)

LogLikelihood = Callable[[Evaluations], np.ndarray]


@dataclass(frozen=True)
class SMCOptions:
    """Settings of :func:`smc`."""

    n_particles: int = 400
    ess_target: float = 0.5
    resample_threshold: float = 0.5
    n_mcmc_steps: int = 5
    n_final_steps: int = 0
    proposal_scale: float | None = None
    level: float = 0.9
    max_iter: int = 1000

    def __post_init__(self):
        check_option("n_particles", self.n_particles, low=2, integer=True)
        check_option("ess_target", self.ess_target, low=0.0, high=1.0,
                     low_open=True, high_open=True)
        check_option("resample_threshold", self.resample_threshold, low=0.0, high=1.0)
        check_option("n_mcmc_steps", self.n_mcmc_steps, low=1, integer=True)
        check_option("n_final_steps", self.n_final_steps, low=0, integer=True)
        check_option("proposal_scale", self.proposal_scale, low=0.0, low_open=True, allow_none=True)
        check_option("level", self.level, low=0.0, high=1.0, low_open=True, high_open=True)
        check_option("max_iter", self.max_iter, low=1, integer=True)


def _logsumexp(a: np.ndarray) -> float:
    m = np.max(a)
    if not np.isfinite(m):
        return float(m)
    return float(m + np.log(np.sum(np.exp(a - m))))


def _increment(ll: np.ndarray, delta: float) -> np.ndarray:
    """``delta * ll`` with -inf likelihoods staying -inf (and 0 * -inf = -inf, not nan)."""
    return np.where(np.isfinite(ll), delta * np.where(np.isfinite(ll), ll, 0.0), -np.inf)


def _cess(log_w: np.ndarray, ll: np.ndarray, delta: float) -> float:
    """Conditional ESS / N of the incremental weights for a temperature step ``delta``."""
    inc = _increment(ll, delta)
    return float(np.exp(2 * _logsumexp(log_w + inc) - _logsumexp(log_w + 2 * inc)))


def next_temperature(log_w: np.ndarray, ll: np.ndarray, lam: float, ess_target: float) -> float:
    """Largest lam' in (lam, 1] (to ~1e-15) whose conditional ESS stays at ``ess_target``
    times its value for an infinitesimal step."""
    finite = np.isfinite(ll)
    target = ess_target * float(np.exp(_logsumexp(log_w[finite])))
    room = 1.0 - lam
    if _cess(log_w, ll, room) >= target:
        return 1.0
    lo, hi = 0.0, room
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _cess(log_w, ll, mid) >= target:
            lo = mid
        else:
            hi = mid
    return lam + (lo if lo > 0 else hi)


def systematic_resample(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices drawn by systematic resampling (one uniform, low variance)."""
    n = weights.size
    positions = (rng.uniform() + np.arange(n)) / n
    cdf = np.cumsum(weights)
    cdf[-1] = 1.0
    return np.searchsorted(cdf, positions, side="right").clip(0, n - 1)


def smc(
    objective: Objective,
    space: SearchSpace,
    *,
    options: SMCOptions = SMCOptions(),
    rng: np.random.Generator,
    callback: IterationCallback | None = None,
    log_likelihood: LogLikelihood,
    x0=None,
) -> EstimationResult:
    """Sample the posterior ``uniform prior x L`` with tempered SMC; ``x`` of the result
    is the lowest-fitness point seen, ``posterior`` the weighted final cloud."""
    o = options
    n, d = int(o.n_particles), space.dim
    scale = (2.38**2 / d) if o.proposal_scale is None else float(o.proposal_scale)
    t = Tracker("smc", objective, space, rng, callback)

    def loglik(ev: Evaluations) -> np.ndarray:
        ll = np.asarray(log_likelihood(ev), dtype=float).reshape(-1)
        if ll.shape != ev.fitness.shape:
            raise ValueError(f"log_likelihood returned shape {ll.shape} for {ev.fitness.size} rows")
        return np.where(ev.failed | ~np.isfinite(ll), -np.inf, ll)

    U = rng.uniform(size=(n, d))
    ev = t.evaluate(U)
    fit, failed, ll = ev.fitness, ev.failed, loglik(ev)
    log_w = np.full(n, -np.log(n))
    lam, log_z, stage = 0.0, 0.0, 0

    def weights() -> np.ndarray:
        return np.exp(log_w - _logsumexp(log_w))

    def record(extras) -> None:
        w = weights()
        ess = 1.0 / np.sum(w**2)
        t.record(U, fit, failed, w, {"temperature": np.float64(lam), "stage": np.int64(stage),
                                     "ess": np.float64(ess), "log_evidence": np.float64(log_z),
                                     "loglik": ll.copy(), **extras})

    def move(chol: np.ndarray) -> None:
        nonlocal U, fit, failed, ll
        prop = U + rng.standard_normal((n, d)) @ chol.T
        log_u = np.log(rng.uniform(size=n))
        inside = np.all((prop >= 0.0) & (prop <= 1.0), axis=1)
        ll_p = np.full(n, -np.inf)
        fit_p, failed_p = np.full(n, np.inf), np.ones(n, dtype=bool)
        if inside.any():
            ev_p = t.evaluate(prop[inside])
            ll_p[inside], fit_p[inside], failed_p[inside] = loglik(ev_p), ev_p.fitness, ev_p.failed
        with np.errstate(invalid="ignore"):
            log_alpha = lam * (ll_p - ll)  # -inf - -inf = nan: rejected below
        accept = inside & (log_u < log_alpha)
        U, ll = np.where(accept[:, None], prop, U), np.where(accept, ll_p, ll)
        fit, failed = np.where(accept, fit_p, fit), np.where(accept, failed_p, failed)
        record({"acceptance": np.float64(accept.mean()), "inside": inside,
                "accepted": accept, "proposals": t.to_physical(prop)})

    def proposal_chol() -> np.ndarray:
        w = weights()
        dev = U - w @ U
        cov = scale * ((w[:, None] * dev).T @ dev) + 1e-12 * np.eye(d)
        try:
            return np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:
            return np.diag(np.sqrt(np.maximum(np.diag(cov), 1e-12)))

    record({})
    reason = None
    while lam < 1.0 and reason is None:
        if not np.isfinite(ll).any():
            reason = "every particle failed or has zero likelihood; cannot temper"
            break
        new_lam = next_temperature(log_w - _logsumexp(log_w), ll, lam, o.ess_target)
        inc = _increment(ll, new_lam - lam)
        log_w = log_w - _logsumexp(log_w)
        log_z += _logsumexp(log_w + inc)
        log_w = log_w + inc
        lam, stage = new_lam, stage + 1
        w = weights()
        if 1.0 / np.sum(w**2) < o.resample_threshold * n:
            idx = systematic_resample(w, rng)
            U, fit, failed, ll = U[idx], fit[idx], failed[idx], ll[idx]
            log_w = np.full(n, -np.log(n))
        chol = proposal_chol()
        for _ in range(o.n_mcmc_steps):
            if t.nit >= o.max_iter:
                reason = f"reached max_iter={o.max_iter} iterations at temperature {lam:.4g} < 1"
                break
            move(chol)
    if reason is None:
        chol = proposal_chol()
        for _ in range(o.n_final_steps):
            if t.nit >= o.max_iter:
                break
            move(chol)
        reason = f"reached temperature 1 after {stage} tempering stages"
    posterior = Uncertainty.from_samples(space.names, t.to_physical(U), weights(), level=o.level, log_evidence=log_z)
    return t.result(reason, posterior)
