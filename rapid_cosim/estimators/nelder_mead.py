"""Nelder-Mead simplex search (scipy's, with bounds) in unit coordinates: the local second
stage of the paper's two-step method (section 3, Step 2).

The simplex starts at ``x0`` (default: the centre of the box) plus ``initial_step`` along
each axis, towards the inside of the box when ``x0`` sits near an upper bound. scipy clips
every vertex into [0, 1], so no evaluated point leaves the bounds.

Each objective call scores one point (shape (1, d)): the simplex is sequential by nature.
One :class:`Iteration` is recorded per scipy iteration and holds the points evaluated
since the previous one (the first also holds the initial simplex). Points evaluated after
scipy's last iteration callback, if any, form one final iteration. The method uses no
randomness; ``rng`` is taken for a uniform signature and its state is recorded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from .base import (EstimationResult, IterationCallback, Objective, SearchSpace, Tracker,
                   check_option, unit_start)

HUGE = 1e300


@dataclass(frozen=True)
class NMOptions:
    """Settings of :func:`nelder_mead`; ``xatol`` is in unit coordinates, ``fatol`` in
    fitness units (scipy stops when both hold), ``adaptive`` scales the moves with the
    dimension (Gao & Han 2012)."""

    max_iter: int = 1000
    max_fev: int = 2000
    initial_step: float = 0.05
    xatol: float = 1e-6
    fatol: float = 1e-10
    adaptive: bool = False

    def __post_init__(self):
        check_option("max_iter", self.max_iter, low=1, integer=True)
        check_option("max_fev", self.max_fev, low=1, integer=True)
        check_option("initial_step", self.initial_step, low=0.0, high=0.5, low_open=True)
        check_option("xatol", self.xatol, low=0.0)
        check_option("fatol", self.fatol, low=0.0)
        if not isinstance(self.adaptive, bool):
            raise ValueError(f"adaptive={self.adaptive!r} is not a bool; allowed: True or False")


def initial_simplex(u0: np.ndarray, step: float) -> np.ndarray:
    """``u0`` and one vertex per axis, stepping down instead of up near the upper bound."""
    d = u0.size
    sim = np.tile(u0, (d + 1, 1))
    for i in range(d):
        sim[i + 1, i] += step if u0[i] + step <= 1.0 else -step
    return sim


def nelder_mead(
    objective: Objective,
    space: SearchSpace,
    *,
    options: NMOptions = NMOptions(),
    rng: np.random.Generator,
    callback: IterationCallback | None = None,
    x0=None,
) -> EstimationResult:
    """Minimise ``objective`` from ``x0`` with scipy's bounded Nelder-Mead."""
    o = options
    d = space.dim
    t = Tracker("nm", objective, space, rng, callback)
    u0 = unit_start(space, x0)
    if u0 is None:
        u0 = np.full(d, 0.5)
    pending_u: list[np.ndarray] = []
    pending_f: list[float] = []
    pending_failed: list[bool] = []

    def fun(u: np.ndarray) -> float:
        ev = t.evaluate(np.asarray(u, dtype=float).reshape(1, d))
        pending_u.append(np.array(u, dtype=float))
        pending_f.append(float(ev.fitness[0]))
        pending_failed.append(bool(ev.failed[0]))
        # scipy's convergence test computes inf - inf = nan and never stops: use a huge
        # finite value instead (the tracker keeps the true +inf)
        return min(float(ev.fitness[0]), HUGE)

    def flush(extras=None) -> None:
        t.record(np.array(pending_u).reshape(-1, d), pending_f, pending_failed, None, extras)
        pending_u.clear(), pending_f.clear(), pending_failed.clear()

    def on_iteration(intermediate_result) -> None:
        flush({"simplex_best": np.asarray(intermediate_result.x, dtype=float).copy()})

    res = minimize(
        fun,
        u0,
        method="Nelder-Mead",
        bounds=[(0.0, 1.0)] * d,
        callback=on_iteration,
        options={
            "maxiter": int(o.max_iter),
            "maxfev": int(o.max_fev),
            "xatol": o.xatol,
            "fatol": o.fatol,
            "adaptive": o.adaptive,
            "initial_simplex": initial_simplex(u0, o.initial_step),
        },
    )
    if pending_u:
        flush()
    return t.result(f"scipy: {res.message}")
