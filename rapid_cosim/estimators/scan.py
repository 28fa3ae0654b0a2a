"""Coordinate scan: each parameter swept over its whole range, the others held at the best
point so far, the best point moved to the best value found.

Why: a limit that the tests never reach, or a deadband too narrow to matter, leaves a
plateau on which the fitness does not depend on that parameter. A swarm or particle
filter that settles on the plateau has no slope to follow back into the narrow valley
where the limit acts, and Nelder-Mead polishes the plateau's best point. A sweep of that
one parameter, with the others where the search left them, steps down into the valley
(in the structure study, a GGOV1 load limit 0.04 pu above the dispatch in a range of
0.6 pu: no point of 5000 drawn at random beat the plateau; the sweep did). The valley
can be as narrow as 2 % of the range, hence 100 points by default. Written as a
chain stage, usually between two local ones: ``pso:10+nm+scan+nm``.

One iteration per parameter swept (``n_points`` evaluations in one objective call, so a
parallel engine runs them together); a sweep over all parameters is repeated at most
``max_iter`` times and stops early when a whole sweep improves nothing. No randomness:
``rng`` is taken for a uniform signature and its state recorded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import EstimationResult, IterationCallback, Objective, SearchSpace, Tracker, check_option, unit_start


@dataclass(frozen=True)
class ScanOptions:
    """Settings of :func:`coordinate_scan`: ``n_points`` evenly spaced values of each
    parameter (in unit coordinates, so log-scaled parameters are swept in the log), and
    at most ``max_iter`` sweeps over all of them."""

    n_points: int = 100
    max_iter: int = 2

    def __post_init__(self):
        check_option("n_points", self.n_points, low=2, integer=True)
        check_option("max_iter", self.max_iter, low=1, integer=True)


def coordinate_scan(
    objective: Objective,
    space: SearchSpace,
    *,
    options: ScanOptions = ScanOptions(),
    rng: np.random.Generator,
    callback: IterationCallback | None = None,
    x0=None,
) -> EstimationResult:
    """Sweep each parameter of ``x0`` (default: the centre of the box) over its range."""
    d = space.dim
    t = Tracker("scan", objective, space, rng, callback)
    u = unit_start(space, x0)
    if u is None:
        u = np.full(d, 0.5)
    t.evaluate(u.reshape(1, d))
    grid = np.linspace(0.0, 1.0, options.n_points)
    for sweep in range(options.max_iter):
        start = t.best_f
        for i in range(d):
            U = np.tile(t.best_u, (grid.size, 1))
            U[:, i] = grid
            ev = t.evaluate(U)
            t.record(U, ev.fitness, ev.failed, None, {"parameter": i})
        if not t.best_f < start:
            return t.result(f"sweep {sweep + 1} improved nothing")
    return t.result(f"{options.max_iter} sweeps")
