"""Multistart least squares: a certified optimum, or a clear statement that it is not.

A model with a limit (a valve rate limit binding all through the rise, a ceiling just
above the dispatch) has a narrow optimum: the fitness is flat wherever the limit does not
act, and a search that settles on the plateau has no slope back into the valley. So the
optimum is not taken from one search: Levenberg-Marquardt (:mod:`.lm`, on the residual
vector, its Jacobian a batch of finite differences) runs from every point of a scrambled
Sobol design over the whole box, plus ``x0`` when given (a nested model's optimum), all in
lockstep. How many starts end at the best point is the evidence that it is the best
point: the waterfall (each start's final fitness, sorted) is kept in the last iteration's
extras (``start_fun``, ``start_u``, ``start_status``, ``start_merged_into``), and
:func:`reached_best` counts the starts within a criterion margin of the best.

``n_starts = 0`` chooses ``6 + 4 d`` starts; ``rounds`` more designs of the same size are
run while fewer than ``min_reached`` starts reach the best (the design's later points,
never a repeat).

Nested models share their starts (``vary``): a model that adds an effect to one already
fitted starts from that fit (``x0``, the effect switched off), from ``x0`` with only the
new effect's parameters (``vary``) moved over a small design of their own, and from a
smaller design over the whole box (``4 + 2 d``) that checks for basins elsewhere. On the
field tests' second-effect round this took a pair from 27 starts to 15.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import qmc

from .base import EstimationResult, IterationCallback, Objective, SearchSpace, Tracker, check_option, unit_start
from .lm import STATUS, LMOptions, levenberg_marquardt


@dataclass(frozen=True)
class MSOptions:
    """Settings of :func:`multistart`: ``n_starts`` (0: ``6 + 4 d``), at most
    ``rounds`` designs while fewer than ``min_reached`` starts end within ``margin`` of
    the best fitness (relative: ``f <= f_best * (1 + margin)``); ``max_iter`` and the
    rest are the Levenberg-Marquardt settings of every start (:class:`~.lm.LMOptions`)."""

    n_starts: int = 0
    rounds: int = 2
    min_reached: int = 3
    margin: float = 1e-4
    vary: tuple[str, ...] = ()  # parameters moved around x0 (a nested model's new ones)
    max_iter: int = LMOptions.max_iter
    fd_step: float = LMOptions.fd_step
    ftol: float = LMOptions.ftol
    xtol: float = LMOptions.xtol
    merge_tol: float = LMOptions.merge_tol

    def __post_init__(self):
        check_option("n_starts", self.n_starts, low=0, integer=True)
        check_option("rounds", self.rounds, low=1, integer=True)
        check_option("min_reached", self.min_reached, low=1, integer=True)
        check_option("margin", self.margin, low=0.0)
        if isinstance(self.vary, str) or not all(isinstance(v, str) for v in self.vary):
            raise ValueError(f"vary={self.vary!r} is not a list of parameter names")
        object.__setattr__(self, "vary", tuple(self.vary))
        self.lm  # the LM settings checked too

    @property
    def lm(self) -> LMOptions:
        return LMOptions(max_iter=self.max_iter, fd_step=self.fd_step, ftol=self.ftol, xtol=self.xtol,
                         merge_tol=self.merge_tol)


def _nested_starts(space: SearchSpace, u0: np.ndarray, vary: tuple[str, ...], rng) -> np.ndarray:
    """``u0`` with the ``vary`` coordinates moved over a Sobol design of their own."""
    idx = [space.names.index(v) for v in vary]
    k = 2 + 2 * len(idx)
    points = qmc.Sobol(len(idx), scramble=True, seed=rng).random_base2(max(1, math.ceil(math.log2(k))))[:k]
    U = np.tile(u0, (k, 1))
    U[:, idx] = points
    return U


def reached_best(fun: np.ndarray, margin: float) -> int:
    """Starts whose final fitness is within ``margin`` (relative) of the best."""
    f = np.asarray(fun, dtype=float)
    ok = np.isfinite(f)
    if not ok.any():
        return 0
    best = float(np.min(f[ok]))
    return int(np.sum(f[ok] <= best + margin * abs(best)))


def multistart(
    objective: Objective,
    space: SearchSpace,
    *,
    options: MSOptions = MSOptions(),
    rng: np.random.Generator,
    callback: IterationCallback | None = None,
    x0=None,
) -> EstimationResult:
    """Levenberg-Marquardt from a Sobol design over the box (and ``x0``)."""
    o = options
    d = space.dim
    lm = o.lm
    t = Tracker("ms", objective, space, rng, callback)
    u0 = unit_start(space, x0)
    unknown = [v for v in o.vary if v not in space.names]
    if unknown:
        raise ValueError(f"vary names {unknown} that are not estimated ({', '.join(space.names)})")
    nested = _nested_starts(space, u0, o.vary, rng) if o.vary and u0 is not None else np.zeros((0, d))
    n = o.n_starts or (4 + 2 * d if len(nested) else 6 + 4 * d)
    sobol = qmc.Sobol(d, scramble=True, seed=rng)
    design = sobol.random_base2(max(1, math.ceil(math.log2(n * o.rounds))))
    all_u, all_f, all_status, all_merged = [], [], [], []
    used = 0
    for round_ in range(o.rounds):
        U = design[used:used + n]
        used += n
        if round_ == 0 and u0 is not None:
            U = np.vstack([u0, nested, U])
        offset = sum(len(f) for f in all_f)

        def waterfall(run, offset=offset):
            merged = np.where(run.merged_into >= 0, run.merged_into + offset, -1)
            return {"start_merged_into": np.concatenate([*all_merged, merged]).astype(float),
                    "start_fun": np.concatenate([*all_f, run.f]),
                    "start_u": np.vstack([*all_u, run.u]),
                    "start_status": np.concatenate([*all_status, run.status]).astype(float)}

        run = levenberg_marquardt(t, U, lm, extras_every=waterfall)
        all_u.append(run.u.copy()), all_f.append(run.f.copy()), all_status.append(run.status.copy())
        all_merged.append(np.where(run.merged_into >= 0, run.merged_into + offset, -1))
        if reached_best(np.concatenate(all_f), o.margin) >= o.min_reached or used + n > len(design):
            break
    f = np.concatenate(all_f)
    reached = reached_best(f, o.margin)
    status = np.concatenate(all_status)
    counts = ", ".join(f"{np.sum(status == k)} {name}" for k, name in enumerate(STATUS) if np.sum(status == k))
    return t.result(f"{len(f)} starts ({counts}); {reached} reached the best")
