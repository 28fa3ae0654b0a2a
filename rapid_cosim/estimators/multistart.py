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

``n_starts = 0`` chooses ``4 + 2 d`` starts; up to ``rounds`` sets of the same size are
run while fewer than ``min_reached`` starts reach the best (the design's next best points,
never a repeat), so that an optimum found by few starts is searched for again.

A set runs in ``waves`` (issue 54): its best-screened half first, the rest only where that
half does not settle it. A wave settles the search when ``min_reached`` starts end at the
best, at one point, and the starts that reached it set out from points at least ``spread``
apart (in the unit box, in some parameter): one basin that draws starts from across the
design leaves none unexplored that the rest of the set, screened worse, would find. Where
the starts that reached the best set out side by side, or ended at several points of the
best fitness while other starts fell short of it (a sloping ridge, whose far end more
starts may still extend), the rest run, as they always did; where every start ended at
the best fitness the ridge is level (a parameter the data leave free) and settles. The
study behind the numbers: ``benchmarks/starts_study.py`` (the first 4 starts of a fit
reached its best in 93 % of a fleet's fits, the first 8 in 98 %).

The starts are the best points of a larger design (``screen`` points per dimension,
scored in one batch): a limit's optimum can be narrow enough for a plain design to miss
it (valve rates with both limits binding, where starts settle where one does not bind:
on an event campaign, 12 plain Sobol starts missed it by 400 in BIC for one seed in
eight; 12 starts from the best of 96 design points found it for eight of eight, at fewer
simulations, since starts in good regions converge sooner).

Nested models share their starts (``vary``): a model that adds an effect to one already
fitted starts from that fit (``x0``, the effect switched off), from ``x0`` with only the
new effect's parameters (``vary``) moved over a small design of their own, and from a
smaller design over the whole box (``2 + d``) that checks for basins elsewhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import qmc

from .base import EstimationResult, IterationCallback, Objective, SearchSpace, Tracker, check_option, unit_start
from .lm import STATUS, LMOptions, levenberg_marquardt

DISTINCT = 0.01  # points of the best fitness further apart than this (relative) in a parameter are two points


@dataclass(frozen=True)
class MSOptions:
    """Settings of :func:`multistart`: ``n_starts`` (0: ``4 + 2 d``), at most
    ``rounds`` designs while fewer than ``min_reached`` starts end within ``margin`` of
    the best fitness (relative: ``f <= f_best * (1 + margin)``); ``max_iter`` and the
    rest are the Levenberg-Marquardt settings of every start (:class:`~.lm.LMOptions`)."""

    n_starts: int = 0
    rounds: int = 3
    min_reached: int = 3
    margin: float = 1e-4
    waves: int = 2  # a set's starts run in up to this many waves (1: all at once)
    spread: float = 0.25  # how far apart (unit box) the starts that reached the best set out, for a wave to settle
    vary: tuple[str, ...] = ()  # parameters moved around x0 (a nested model's new ones)
    screen: int = 24  # design points per dimension scored before the starts are chosen from them
    max_iter: int = LMOptions.max_iter
    fd_step: float = LMOptions.fd_step
    ftol: float = LMOptions.ftol
    xtol: float = LMOptions.xtol
    merge_tol: float = LMOptions.merge_tol
    broyden_every: int = LMOptions.broyden_every

    def __post_init__(self):
        check_option("n_starts", self.n_starts, low=0, integer=True)
        check_option("rounds", self.rounds, low=1, integer=True)
        check_option("min_reached", self.min_reached, low=1, integer=True)
        check_option("margin", self.margin, low=0.0)
        check_option("waves", self.waves, low=1, integer=True)
        check_option("spread", self.spread, low=0.0, high=1.0)
        if isinstance(self.vary, str) or not all(isinstance(v, str) for v in self.vary):
            raise ValueError(f"vary={self.vary!r} is not a list of parameter names")
        object.__setattr__(self, "vary", tuple(self.vary))
        check_option("screen", self.screen, low=0, integer=True)
        self.lm  # the LM settings checked too

    @property
    def lm(self) -> LMOptions:
        return LMOptions(max_iter=self.max_iter, fd_step=self.fd_step, ftol=self.ftol, xtol=self.xtol,
                         merge_tol=self.merge_tol, broyden_every=self.broyden_every)


def _screened_design(t: Tracker, d: int, m: int, rng, keep: int) -> tuple[np.ndarray, dict]:
    """``m`` points of a scrambled Sobol design, scored in one batch (recorded as one
    iteration), best first: the starts are taken from its head. With them, the scores
    of the first ``keep`` (residual rows too), so that a start is not simulated again
    (:func:`~.lm.levenberg_marquardt`'s ``known``)."""
    design = qmc.Sobol(d, scramble=True, seed=rng).random_base2(max(1, math.ceil(math.log2(m))))[:m]
    ev, R = t.evaluate_residuals(design)
    t.record(design, ev.fitness, ev.failed, None, {"screen": np.ones(1)})
    order = np.lexsort((np.arange(m), np.where(ev.failed, np.inf, ev.fitness)))
    known = {design[i].tobytes(): (ev.fitness[i], ev.failed[i], R[i].copy()) for i in order[:keep]}
    return design[order], known


def _nested_starts(space: SearchSpace, u0: np.ndarray, vary: tuple[str, ...], rng) -> np.ndarray:
    """``u0`` with the ``vary`` coordinates moved over a Sobol design of their own."""
    idx = [space.names.index(v) for v in vary]
    k = 2 + 2 * len(idx)
    points = qmc.Sobol(len(idx), scramble=True, seed=rng).random_base2(max(1, math.ceil(math.log2(k))))[:k]
    U = np.tile(u0, (k, 1))
    U[:, idx] = points
    return U


def _top(fun: np.ndarray, margin: float) -> np.ndarray:
    """The starts whose final fitness is within ``margin`` (relative) of the best."""
    f = np.asarray(fun, dtype=float)
    ok = np.isfinite(f)
    if not ok.any():
        return ok
    best = float(np.min(f[ok]))
    return ok & (f <= best + margin * abs(best))


def reached_best(fun: np.ndarray, margin: float) -> int:
    """Starts whose final fitness is within ``margin`` (relative) of the best."""
    return int(np.sum(_top(fun, margin)))


def _others(space: SearchSpace, u_top: np.ndarray, best: np.ndarray) -> list[np.ndarray]:
    """The end points (of starts at the best fitness) other than the best point: more
    than DISTINCT apart from it, relative, in some parameter."""
    points = space.from_unit(np.clip(u_top, 0.0, 1.0))
    scale = np.maximum(np.abs(best), 1e-12)
    return [x for x in points if np.any(np.abs(x - best) > DISTINCT * scale)]


class _Starts:
    """The starts run so far, across designs: each one's end point, fitness, status and
    the start it merged into; what the waterfall records."""

    def __init__(self):
        self.u, self.f, self.status, self.merged, self.origins = [], [], [], [], []

    def extras(self, run=None) -> dict:
        """The waterfall so far, with ``run``'s starts as they stand."""
        u, f, st, mg = list(self.u), list(self.f), list(self.status), list(self.merged)
        if run is not None:
            offset = sum(len(x) for x in self.f)
            u, f, st = u + [run.u], f + [run.f], st + [run.status]
            mg = mg + [np.where(run.merged_into >= 0, run.merged_into + offset, -1)]
        return {"start_merged_into": np.concatenate(mg).astype(float), "start_fun": np.concatenate(f),
                "start_u": np.vstack(u), "start_status": np.concatenate(st).astype(float)}

    def run(self, t: Tracker, U: np.ndarray, lm: LMOptions, known: dict):
        offset = sum(len(f) for f in self.f)
        run = levenberg_marquardt(t, U, lm, extras_every=self.extras, known=known)
        self.origins.append(np.array(U, dtype=float))
        self.u.append(run.u.copy()), self.f.append(run.f.copy()), self.status.append(run.status.copy())
        self.merged.append(np.where(run.merged_into >= 0, run.merged_into + offset, -1))
        return run

    @property
    def fun(self) -> np.ndarray:
        return np.concatenate(self.f)

    def settled(self, space: SearchSpace, best: np.ndarray, o: "MSOptions") -> bool:
        """Whether ``min_reached`` starts reached the best from points ``spread`` apart, all
        at one point or every start there. Starts that reach the best fitness at several
        points, with others short of it, lie along a sloping ridge whose far end more
        starts may still extend (a fleet unit's rate-limited IEEEG1, issue 54); where every
        start reached it, the ridge is level: a parameter the data leave free."""
        top = _top(self.fun, o.margin)
        if np.sum(top) < o.min_reached:
            return False
        at_best = np.vstack(self.origins)[top]
        apart = np.max(np.abs(at_best[:, None, :] - at_best[None, :, :]), axis=2)
        level = bool(np.all(top)) or not _others(space, np.vstack(self.u)[top], best)
        return bool(np.max(apart) >= o.spread) and level


def multistart(
    objective: Objective,
    space: SearchSpace,
    *,
    options: MSOptions = MSOptions(),
    rng: np.random.Generator,
    callback: IterationCallback | None = None,
    x0=None,
) -> EstimationResult:
    """Levenberg-Marquardt from the best points of a Sobol design over the box (and from
    ``x0``), in rounds while too few starts reach the best."""
    o = options
    d = space.dim
    lm = o.lm
    t = Tracker("ms", objective, space, rng, callback)
    u0 = unit_start(space, x0)
    unknown = [v for v in o.vary if v not in space.names]
    if unknown:
        raise ValueError(f"vary names {unknown} that are not estimated ({', '.join(space.names)})")
    nested = _nested_starts(space, u0, o.vary, rng) if o.vary and u0 is not None else np.zeros((0, d))
    n = o.n_starts or (2 + d if len(nested) else 4 + 2 * d)
    screen = o.screen * d if not len(nested) else o.screen * d // 3  # a nested model mostly starts from its fit
    design, known = _screened_design(t, d, max(n * o.rounds, screen), rng, keep=n * o.rounds)
    starts, used = _Starts(), 0
    for round_ in range(o.rounds):
        U = design[used:used + n]
        used += n
        if round_ == 0 and u0 is not None:
            U = np.vstack([u0, nested, U])
        for k, wave in enumerate(np.array_split(U, min(o.waves, len(U)))):
            starts.run(t, wave, lm, known)
            if k < o.waves - 1 and starts.settled(space, t.best_x, o):
                break
        if reached_best(starts.fun, o.margin) >= o.min_reached or used + n > len(design):
            break
    f = starts.fun
    reached = reached_best(f, o.margin)
    status = np.concatenate(starts.status)
    counts = ", ".join(f"{np.sum(status == k)} {name}" for k, name in enumerate(STATUS) if np.sum(status == k))
    return t.result(f"{len(f)} starts ({counts}); {reached} reached the best"
                    + elsewhere(space, np.vstack(starts.u), f, o.margin, t.best_x))


def elsewhere(space: SearchSpace, u: np.ndarray, f: np.ndarray, margin: float, best: np.ndarray) -> str:
    """What the stop reason adds when starts reach the best fitness at points other than
    the best (more than DISTINCT apart, relative, in some parameter): the fit then does
    not fix those parameters, however many starts reached it. Two points that differ by
    two parameters' values swapped are named as such (two lags in series, no limit
    between them: :mod:`rapid_cosim.structures.identifiability`)."""
    other = _others(space, u[_top(f, margin)], best)
    if not other:
        return ""
    scale = np.maximum(np.abs(best), 1e-12)
    far = max(other, key=lambda x: float(np.max(np.abs(x - best) / scale)))
    moved = [k for k in range(best.size) if abs(far[k] - best[k]) > DISTINCT * scale[k]]
    near = lambda a, b: abs(a - b) <= DISTINCT * max(abs(a), abs(b), 1e-12)  # noqa: E731
    if len(moved) == 2 and near(far[moved[0]], best[moved[1]]) and near(far[moved[1]], best[moved[0]]):
        a, b = (space.names[k] for k in moved)
        return (f"; {len(other)} of them at {a} and {b} exchanged ({best[moved[0]]:.4g} and {best[moved[1]]:.4g} "
                "either way round): the fit does not tell which is which")
    spans = ", ".join(f"{space.names[k]} {best[k]:.4g} and {far[k]:.4g}" for k in moved)
    return f"; {len(other)} of them elsewhere ({spans}): the best fitness does not fix those parameters"
