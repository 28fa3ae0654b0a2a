"""Profile likelihoods: the best fit with one parameter held at each value of a grid.

A profile shows what a point estimate and its Laplace interval cannot: an optimum in a
narrow valley (a rate limit that binds only between two values), a parameter that does
not matter over part of its range (the profile goes flat where a limit stops binding),
and a second basin. Every grid point is a Levenberg-Marquardt fit of the other
parameters (:mod:`.lm`) from the best point with the one parameter moved, all grid points
in lockstep (one objective call per iteration), as pyPESTO's ``profile`` does with its
optimiser.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import Objective, SearchSpace, Tracker
from .lm import LMOptions, levenberg_marquardt


@dataclass(frozen=True)
class Profile:
    """``fitness[k]`` is the best fitness with ``name`` held at ``values[k]``; ``x[k]``
    the point it was reached at (physical units)."""

    name: str
    values: np.ndarray
    fitness: np.ndarray
    x: np.ndarray

    def interval(self, n_samples: int, level_delta: float = 2.71) -> tuple[float, float]:
        """Values whose profile stays within ``level_delta`` of the best in the criterion
        (the deviance ``N log(f / f_best)``; 2.71: a 90 % likelihood-ratio interval)."""
        f = self.fitness
        ok = np.isfinite(f)
        if not ok.any():
            return (float("nan"), float("nan"))
        delta = n_samples * np.log(f / np.min(f[ok]))
        inside = self.values[ok & (delta <= level_delta)]
        return (float(inside.min()), float(inside.max())) if inside.size else (float("nan"), float("nan"))


LOCAL = (0.0025, 0.005, 0.01, 0.02, 0.04)  # unit-coordinate offsets resolving a narrow optimum


def grid(space: SearchSpace, index: int, n: int, around: float | None = None) -> np.ndarray:
    """``n`` values evenly spaced in unit coordinates over the parameter's range (in the
    log for log-scaled ones), plus, given the optimum ``around``, the optimum and points
    at :data:`LOCAL` either side of it: an optimum as narrow as a limit that binds only
    near one value is resolved, not stepped over."""
    u = list(np.linspace(0.0, 1.0, n))
    if around is not None:
        u0 = float(np.clip(space.to_unit(np.where(np.arange(space.dim) == index, around, space.lower))[index], 0, 1))
        u += [u0] + [u0 + s * d for d in LOCAL for s in (-1, 1) if 0.0 <= u0 + s * d <= 1.0]
    base = np.tile(space.to_unit(space.lower + 0.5 * space.width), (len(u), 1))
    base[:, index] = u
    values = space.clip(space.from_unit(base))[:, index]
    if around is not None:
        values[n] = around  # exactly the optimum, not its round trip through unit coordinates
    return np.unique(values)


def profile(objective: Objective, space: SearchSpace, x_best: np.ndarray, index: int, values: np.ndarray, *,
            rng: np.random.Generator, options: LMOptions = LMOptions(max_iter=20, merge_tol=0.0)) -> Profile:
    """The profile of parameter ``index`` over ``values`` (physical units), each point
    fitted from ``x_best`` with that parameter moved."""
    x_best = np.asarray(x_best, dtype=float)
    t = Tracker("profile", objective, space, rng, None)
    X = np.tile(x_best, (len(values), 1))
    X[:, index] = values
    U0 = np.clip(space.to_unit(X), 0.0, 1.0)
    fixed = np.zeros_like(U0, dtype=bool)
    fixed[:, index] = True
    run = levenberg_marquardt(t, U0, options, fixed=fixed)
    return Profile(space.names[index], np.asarray(values, dtype=float), run.f.copy(),
                   space.clip(space.from_unit(run.u)))
