"""Particle filter of the paper (section 2.3, Algorithm 1), used as a global optimiser.

Where Algorithm 1 is ambiguous, this module chooses as follows (all in unit coordinates):

* **Weights.** ``W = 1 - f / sum(f)`` as in line 16, clipped to [0, 1] and normalised.
  Fitness is assumed non-negative (an RSSD); failed evaluations carry their penalty
  fitness, and a non-finite fitness gets ``W = 0``.
* **Pruning (epsilon).** The paper calls epsilon a threshold on W but also "the
  percentage of particles with lowest weight that will not survive". With
  ``W = 1 - f/sum f`` every W is close to 1 for a cloud of any size, so a raw threshold
  prunes nothing or everything. We read epsilon as the *share* pruned: the
  ``floor(epsilon * N)`` lowest-weight particles die (ties by order), and parents are
  drawn among the survivors with probability proportional to W.
* **Resampling.** Each child is its parent plus a Gaussian kernel with covariance
  ``sigma_k * I`` (the paper's sigma_K), reflected at the faces of the box. Reflection
  keeps the kernel's mass inside without piling particles onto the bounds as clipping
  would.
* **Kernel decay.** A fixed kernel cannot localise the optimum finer than its own width,
  so sigma_K is multiplied by ``kernel_decay`` after every iteration. ``1.0`` reproduces
  the paper; the default 0.8 shrinks the kernel's standard deviation ~3x in 10
  iterations and ~10x in 20, enough for a few-iteration first stage before a local
  method and for a standalone run of a few dozen iterations.
* **Elitism.** The best particle found so far is carried into every new cloud (as row 0,
  with its known fitness, not re-simulated), so the filter never loses its best point.
* **x0.** The prior stays uniform in the bounds; a given ``x0`` replaces one of the
  initial particles.

One iteration = one objective call on the whole new cloud. Stops at ``max_iter``
iterations, when the best fitness reaches ``fitness_tol``, or when the cloud's largest
standard deviation (unit coordinates) falls below ``spread_tol``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import (EstimationResult, IterationCallback, Objective, SearchSpace, Tracker,
                   check_option, initial_population, reflect_unit)


@dataclass(frozen=True)
class PFOptions:
    """Settings of :func:`particle_filter`.

    ``sigma_k`` is the kernel's covariance (times identity) in unit coordinates, so the
    default 0.01 is a standard deviation of 10 % of each parameter's range; ``epsilon``
    is the share of particles pruned per iteration.
    """

    n_particles: int = 50
    max_iter: int = 30
    epsilon: float = 0.5
    sigma_k: float = 0.01
    kernel_decay: float = 0.8
    fitness_tol: float | None = None
    spread_tol: float = 1e-4

    def __post_init__(self):
        check_option("n_particles", self.n_particles, low=2, integer=True)
        check_option("max_iter", self.max_iter, low=1, integer=True)
        check_option("epsilon", self.epsilon, low=0.0, high=1.0, high_open=True)
        check_option("sigma_k", self.sigma_k, low=0.0, low_open=True)
        check_option("kernel_decay", self.kernel_decay, low=0.0, high=1.0, low_open=True)
        check_option("fitness_tol", self.fitness_tol, allow_none=True)
        check_option("spread_tol", self.spread_tol, low=0.0)


def pf_weights(fitness: np.ndarray) -> np.ndarray:
    """Normalised weights ``W = 1 - f/sum f`` (line 16 of Algorithm 1)."""
    finite = np.isfinite(fitness)
    total = fitness[finite].sum()
    w = np.zeros(fitness.shape)
    w[finite] = 1.0 - fitness[finite] / total if total != 0 else 1.0
    w = np.clip(w, 0.0, 1.0)
    s = w.sum()
    return w / s if s > 0 else np.full(fitness.shape, 1.0 / fitness.size)


def particle_filter(
    objective: Objective,
    space: SearchSpace,
    *,
    options: PFOptions = PFOptions(),
    rng: np.random.Generator,
    callback: IterationCallback | None = None,
    x0=None,
) -> EstimationResult:
    """Minimise ``objective`` over ``space`` with the particle filter of Algorithm 1."""
    o = options
    n, d = int(o.n_particles), space.dim
    t = Tracker("pf", objective, space, rng, callback)
    U = initial_population(space, n, rng, x0)
    sigma_k = float(o.sigma_k)
    n_keep = n - int(np.floor(o.epsilon * n))
    evaluated = np.ones(n, dtype=bool)  # after the first iteration, row 0 is the elite
    elite_f, elite_failed = np.inf, True
    while True:
        ev = t.evaluate(U[evaluated])
        fitness = np.full(n, elite_f)
        fitness[evaluated] = ev.fitness
        failed = np.full(n, elite_failed)
        failed[evaluated] = ev.failed
        w = pf_weights(fitness)
        spread = float(U.std(axis=0).max())
        t.record(U, fitness, failed, w, {"sigma_k": np.float64(sigma_k),
                                         "spread": np.float64(spread),
                                         "evaluated": evaluated})
        if o.fitness_tol is not None and t.best_f <= o.fitness_tol:
            reason = f"best fitness {t.best_f:.6g} <= fitness_tol={o.fitness_tol:g}"
            break
        if spread < o.spread_tol:
            reason = f"particle spread {spread:.3g} < spread_tol={o.spread_tol:g}"
            break
        if t.nit >= o.max_iter:
            reason = f"reached max_iter={o.max_iter} iterations"
            break
        # prune the lowest-weight share, draw parents among survivors by weight
        order = np.argsort(-w, kind="stable")
        survivors = order[:n_keep]
        p = w[survivors]
        p = p / p.sum() if p.sum() > 0 else np.full(n_keep, 1.0 / n_keep)
        parents = survivors[rng.choice(n_keep, size=n - 1, p=p)]
        children = reflect_unit(U[parents] + np.sqrt(sigma_k) * rng.standard_normal((n - 1, d)))
        elite_f, elite_failed = t.best_f, t.best_failed
        U = np.vstack([t.best_u, children])
        evaluated = np.r_[False, np.ones(n - 1, dtype=bool)]
        sigma_k *= o.kernel_decay
    return t.result(reason)
