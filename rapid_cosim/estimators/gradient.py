"""Projected steepest descent with finite-difference gradients and an Armijo line search:
the "naive" local second stage of the paper (section 3, Step 2).

Everything is in unit coordinates, so one step length means the same for every parameter.

* **Gradient.** Forward (d points) or central (2 d points) differences with step
  ``fd_step``; the whole stencil is scored in ONE objective call, so a parallel evaluator
  runs it at once. A stencil point that would leave the box is mirrored to the other side
  (forward) or shortened to the face (central). A component whose stencil contains a
  failed simulation is set to zero: its direction is unknown, and the line search must not
  move along it.
* **Step.** Trial points ``clip(u - s g / |g|_inf, 0, 1)`` (a projected step whose largest
  component is ``s``), accepted under the projected Armijo condition
  ``f(u') <= f(u) + c1 g.(u' - u)``; otherwise ``s`` is halved (each trial is one
  objective call: backtracking is sequential). The next iteration tries twice the last
  accepted ``s`` (at most ``max_step``), so the step adapts to the valley.
* **Stop** at ``max_iter`` iterations, when the projected gradient ``|clip(u - g) - u|_inf``
  is below ``gtol``, when the accepted step is below ``xtol``, when the relative decrease
  is below ``ftol``, when the line search finds no decrease in ``max_backtracks``
  halvings, or when every component's stencil failed (no usable gradient, e.g. a start
  inside a region where simulations fail).

One :class:`Iteration` holds the stencil and the line-search points of one step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import (EstimationResult, IterationCallback, Objective, SearchSpace, Tracker,
                   check_option, unit_start)

DIFFERENCES = ("forward", "central")


@dataclass(frozen=True)
class GDOptions:
    """Settings of :func:`gradient_descent` (steps in unit coordinates)."""

    max_iter: int = 200
    difference: str = "central"
    fd_step: float = 1e-3
    initial_step: float = 0.05
    max_step: float = 0.5
    armijo_c1: float = 1e-4
    max_backtracks: int = 30
    gtol: float = 1e-12
    xtol: float = 1e-9
    ftol: float = 1e-14

    def __post_init__(self):
        check_option("max_iter", self.max_iter, low=1, integer=True)
        if self.difference not in DIFFERENCES:
            raise ValueError(f"difference={self.difference!r} is not known; allowed: {DIFFERENCES}")
        check_option("fd_step", self.fd_step, low=0.0, high=0.5, low_open=True)
        check_option("initial_step", self.initial_step, low=0.0, high=1.0, low_open=True)
        check_option("max_step", self.max_step, low=0.0, high=1.0, low_open=True)
        check_option("armijo_c1", self.armijo_c1, low=0.0, high=1.0, low_open=True, high_open=True)
        check_option("max_backtracks", self.max_backtracks, low=1, integer=True)
        check_option("gtol", self.gtol, low=0.0)
        check_option("xtol", self.xtol, low=0.0)
        check_option("ftol", self.ftol, low=0.0)


def stencil(u: np.ndarray, h: float, difference: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points ``a`` and ``b`` per axis with g_i = (f(a_i) - f(b_i)) / (a_i - b_i); for forward
    differences ``b`` is ``u`` itself (not re-evaluated). Returns (points, a_i, b_i)."""
    d = u.size
    eye = np.eye(d)
    if difference == "forward":
        hi = np.where(u + h <= 1.0, u + h, u - h)
        pts = u + eye * (hi - u)
        return pts, hi, u.copy()
    up, down = np.minimum(u + h, 1.0), np.maximum(u - h, 0.0)
    pts = np.vstack([u + eye * (up - u), u + eye * (down - u)])
    return pts, up, down


def gradient_descent(
    objective: Objective,
    space: SearchSpace,
    *,
    options: GDOptions = GDOptions(),
    rng: np.random.Generator,
    callback: IterationCallback | None = None,
    x0=None,
) -> EstimationResult:
    """Minimise ``objective`` from ``x0`` (default: centre of the box) by projected
    steepest descent."""
    o = options
    d = space.dim
    t = Tracker("gd", objective, space, rng, callback)
    u = unit_start(space, x0)
    u = np.full(d, 0.5) if u is None else u
    f = None
    step = float(o.initial_step)
    reason = f"reached max_iter={o.max_iter} iterations"
    while t.nit < o.max_iter:
        pts, a, b = stencil(u, o.fd_step, o.difference)
        if f is None:  # first iteration: score the start with the stencil
            pts = np.vstack([u, pts])
        ev = t.evaluate(pts)
        fit, bad = ev.fitness, ev.failed
        if f is None:
            f, f_failed = float(fit[0]), bool(bad[0])
            fit, bad = fit[1:], bad[1:]
        if o.difference == "forward":
            fa, fb, bad_i = fit, np.full(d, f), bad | f_failed
        else:
            fa, fb, bad_i = fit[:d], fit[d:], bad[:d] | bad[d:]
        with np.errstate(invalid="ignore"):
            g = np.where(bad_i, 0.0, (fa - fb) / (a - b))
        g = np.where(np.isfinite(g), g, 0.0)
        xs, fs, fails = [pts], [ev.fitness], [ev.failed]
        pg = float(np.abs(np.clip(u - g, 0.0, 1.0) - u).max())
        accepted = False
        moved = 0.0
        if pg > o.gtol:
            gmax = np.abs(g).max()
            s = min(step, o.max_step)
            for _ in range(o.max_backtracks):
                trial = np.clip(u - s * g / gmax, 0.0, 1.0)
                ev_t = t.evaluate(trial[None, :])
                xs.append(trial[None, :]), fs.append(ev_t.fitness), fails.append(ev_t.failed)
                ft = float(ev_t.fitness[0])
                if not ev_t.failed[0] and ft <= f + o.armijo_c1 * float(g @ (trial - u)):
                    accepted = True
                    break
                s *= 0.5
        f_old = f
        if accepted:
            moved = float(np.abs(trial - u).max())
            u, f, f_failed = trial, ft, False
            step = min(2.0 * s, o.max_step)
        t.record(np.vstack(xs), np.concatenate(fs), np.concatenate(fails), None,
                 {"gradient": g, "step": np.float64(moved), "u": u.copy()})
        if bad_i.all():
            reason = "no usable gradient: every finite-difference stencil had a failed simulation"
            break
        if pg <= o.gtol:
            reason = f"projected gradient {pg:.3g} <= gtol={o.gtol:g}"
            break
        if not accepted:
            reason = f"line search found no decrease in max_backtracks={o.max_backtracks} halvings"
            break
        if moved < o.xtol:
            reason = f"step {moved:.3g} < xtol={o.xtol:g}"
            break
        if f_old - f <= o.ftol * abs(f_old):
            reason = f"decrease {f_old - f:.3g} <= ftol * |f| (ftol={o.ftol:g})"
            break
    return t.result(reason)
