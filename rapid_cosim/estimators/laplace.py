"""Gaussian approximation of a posterior around an optimum (Laplace's method).

Cheaper than sampling by orders of magnitude (two batches of 1 + 2d + 2d(d-1)
evaluations) and good enough to put an interval on a calibrated parameter or to compare
estimates from different tests. The Hessian of the negative log-likelihood is taken by
central differences in unit coordinates (log-scaled parameters by their logarithm). Two
passes: the first with steps of 1 % of each range gives a rough covariance; the second
steps ``rel_step`` standard deviations (within [1e-4, 5e-2] of the range), so the
difference quotients see the curvature on the scale that matters rather than the
solver's noise or the model's nonlinearity far away.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from .base import SearchSpace
from .uncertainty import Uncertainty, _inverse


def hessian_stencil(u: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Points of the central-difference Hessian: u, u +- h_i e_i, u +- h_i e_i +- h_j e_j."""
    d = u.size
    points = [u.copy()]
    for i in range(d):
        for s in (1, -1):
            p = u.copy()
            p[i] += s * h[i]
            points.append(p)
    for i in range(d):
        for j in range(i + 1, d):
            for si, sj in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                p = u.copy()
                p[i] += si * h[i]
                p[j] += sj * h[j]
                points.append(p)
    return np.array(points)


def hessian_from_stencil(f: np.ndarray, h: np.ndarray) -> np.ndarray:
    """The Hessian from values at :func:`hessian_stencil`'s points (same order)."""
    d = h.size
    f0 = f[0]
    H = np.zeros((d, d))
    for i in range(d):
        H[i, i] = (f[1 + 2 * i] - 2 * f0 + f[2 + 2 * i]) / h[i] ** 2
    k = 1 + 2 * d
    for i in range(d):
        for j in range(i + 1, d):
            fpp, fpm, fmp, fmm = f[k:k + 4]
            H[i, j] = H[j, i] = (fpp - fpm - fmp + fmm) / (4 * h[i] * h[j])
            k += 4
    return H


def laplace(neg_log_likelihood: Callable[[np.ndarray], np.ndarray], space: SearchSpace, x: np.ndarray, *,
            rel_step: float = 0.5, level: float = 0.9) -> Uncertainty:
    """``neg_log_likelihood`` maps rows of physical parameter sets (n, d) to values (n,),
    evaluated in one call per pass (so a parallel objective parallelises the stencil)."""
    x = np.asarray(x, dtype=float)
    u_x = space.to_unit(x)
    count = 0
    shifted = np.zeros(space.dim, dtype=bool)

    def hessian(h):
        nonlocal count, shifted
        # Parameters are not simulated outside their bounds: at a bound the stencil is
        # centred one step inside (the curvature there stands in for that at the bound).
        u = np.clip(u_x, h, 1 - h)
        shifted = u != u_x
        points = hessian_stencil(u, h)
        count += len(points)
        return hessian_from_stencil(np.asarray(neg_log_likelihood(space.from_unit(points)), dtype=float), h)

    h = np.full(space.dim, 0.01)
    sd = np.sqrt(np.abs(np.diag(_inverse(hessian(h)))))
    h = np.clip(np.where(np.isfinite(sd), rel_step * sd, 0.01), 1e-4, 5e-2)
    H_unit = hessian(h)
    # unit -> physical: x = g(u) with a diagonal Jacobian J = dx/du
    eps = 1e-7
    u = np.clip(u_x, h, 1 - h)
    J = (space.from_unit(np.minimum(u + eps, 1)) - space.from_unit(np.maximum(u - eps, 0))) / (2 * eps)
    H = H_unit / np.outer(J, J)
    at_bound = tuple(n for n, moved in zip(space.names, shifted) if moved)
    return Uncertainty.from_hessian(space.names, x, H, level=level, steps=h * np.abs(J), evaluations=count,
                                    at_bound=at_bound)
