"""Particle swarm optimisation with the update of the paper's eq. (12), in unit coordinates.

    V_t = a1 R1 V_{t-1} + a2 R2 (P_b - X_{t-1}) + a3 R3 (p_b - X_{t-1}),   X_t = X_{t-1} + V_t

R1, R2, R3 are drawn uniform on [0, 1) independently per particle and dimension. Note that
eq. (12) also randomises the inertia term (R1), which halves its mean compared with the
usual "w V" form: the swarm is damped a little more than the textbook one.

Choices:

* **Defaults** a1 = 0.7298, a2 = a3 = 1.49618 are the constriction-equivalent constants
  of Clerc & Kennedy (2002), recommended by Eberhart & Shi (2000) and used by SPSO; a
  swarm of 20 particles is the usual size for a handful of parameters.
* **Initial velocities** are zero (Engelbrecht 2012: random initial velocities mostly
  throw particles out of the box in the first iterations).
* **Velocity limit** ``v_max`` caps each velocity component (fraction of the parameter's
  range per iteration); None disables it. The default 0.5 only stops wild jumps.
* **Bounds.** A position leaving [0, 1] is clamped to the face and that velocity
  component set to zero ("absorbing wall"), so the particle can leave the face at the
  next step under the pull of the bests; every evaluated point is inside the box.
* **x0** replaces one particle of the uniform initial swarm.

One iteration = one objective call on the whole swarm (the first one scores the initial
swarm). Stops at ``max_iter`` iterations, when the best fitness reaches ``fitness_tol``,
or when the global best has not improved by more than ``stall_tol`` (relative) for
``stall_iter`` consecutive iterations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import (EstimationResult, IterationCallback, Objective, SearchSpace, Tracker,
                   check_option, initial_population)


@dataclass(frozen=True)
class PSOOptions:
    """Settings of :func:`pso` (alpha1..3 are a1..a3 of eq. 12)."""

    n_particles: int = 20
    max_iter: int = 100
    alpha1: float = 0.7298
    alpha2: float = 1.49618
    alpha3: float = 1.49618
    v_max: float | None = 0.5
    fitness_tol: float | None = None
    stall_iter: int = 20
    stall_tol: float = 1e-6

    def __post_init__(self):
        check_option("n_particles", self.n_particles, low=1, integer=True)
        check_option("max_iter", self.max_iter, low=1, integer=True)
        for name in ("alpha1", "alpha2", "alpha3"):
            check_option(name, getattr(self, name), low=0.0)
        check_option("v_max", self.v_max, low=0.0, low_open=True, allow_none=True)
        check_option("fitness_tol", self.fitness_tol, allow_none=True)
        check_option("stall_iter", self.stall_iter, low=1, integer=True)
        check_option("stall_tol", self.stall_tol, low=0.0)


def pso(
    objective: Objective,
    space: SearchSpace,
    *,
    options: PSOOptions = PSOOptions(),
    rng: np.random.Generator,
    callback: IterationCallback | None = None,
    x0=None,
) -> EstimationResult:
    """Minimise ``objective`` over ``space`` with the swarm of eq. (12)."""
    o = options
    n, d = int(o.n_particles), space.dim
    t = Tracker("pso", objective, space, rng, callback)
    X = initial_population(space, n, rng, x0)
    V = np.zeros((n, d))
    pbest_x, pbest_f = X.copy(), np.full(n, np.inf)
    pbest_failed = np.ones(n, dtype=bool)
    stall, last_best = 0, np.inf
    while True:
        ev = t.evaluate(X)
        # like the global best: a successful run beats a failed one, then lower fitness wins
        better = (ev.failed < pbest_failed) | ((ev.failed == pbest_failed) & (ev.fitness < pbest_f))
        pbest_x[better], pbest_f[better] = X[better], ev.fitness[better]
        pbest_failed[better] = ev.failed[better]
        t.record(X, ev.fitness, ev.failed, None, {"velocity": V.copy()})
        if np.isfinite(last_best):
            improved = t.best_f < last_best - o.stall_tol * abs(last_best)
        else:
            improved = bool(np.isfinite(t.best_f))
        stall = 0 if improved else stall + 1
        last_best = t.best_f if improved else last_best
        if o.fitness_tol is not None and t.best_f <= o.fitness_tol:
            reason = f"best fitness {t.best_f:.6g} <= fitness_tol={o.fitness_tol:g}"
            break
        if t.nit >= o.max_iter:
            reason = f"reached max_iter={o.max_iter} iterations"
            break
        if stall >= o.stall_iter:
            reason = (f"no improvement of the best fitness by more than stall_tol={o.stall_tol:g}"
                      f" in {o.stall_iter} iterations")
            break
        R1, R2, R3 = rng.uniform(size=(3, n, d))
        V = o.alpha1 * R1 * V + o.alpha2 * R2 * (pbest_x - X) + o.alpha3 * R3 * (t.best_u - X)
        if o.v_max is not None:
            V = np.clip(V, -o.v_max, o.v_max)
        X = X + V
        out = (X < 0.0) | (X > 1.0)
        X = np.clip(X, 0.0, 1.0)
        V[out] = 0.0
    return t.result(reason)
