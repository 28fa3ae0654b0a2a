"""What every estimator shares: the objective it calls, the record of one iteration and
the result (the search space and a batch's scores come from :mod:`rapid_cosim.fitting.search`).

Estimators are plain functions ``method(objective, space, *, options, rng, callback, x0)``
returning an :class:`EstimationResult`, in the manner of ``scipy.optimize``. They never
know how evaluations are scheduled (the objective may fan out to processes or a dask
cluster) nor how iterations are stored (the archive is one ``callback``).

Determinism is a contract: given the same objective values, the same options and an
``rng`` in the same state, a method makes exactly the same calls in the same order. The
archive relies on this to re-run a run bit for bit and to resume one by replay.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from ..fitting.search import Evaluations, SearchSpace
from .uncertainty import Uncertainty


class Objective(Protocol):
    """Scores parameter sets given as rows of ``X`` (physical units, shape (n, d))."""

    def __call__(self, X: np.ndarray) -> Evaluations: ...


@dataclass(frozen=True)
class Iteration:
    """One iteration of one stage, as the archive stores it.

    ``x``/``fitness``/``weights``/``failed`` hold the points evaluated in this iteration
    (the particle cloud for PF, SMC and PSO; the new simplex points for Nelder-Mead; the
    gradient stencil and line-search points for gradient descent). ``rng_state`` is the
    generator's state after the iteration, as ``json.dumps(rng.bit_generator.state)``.
    ``extras`` carries method-specific arrays worth keeping (velocities, temperature...).
    """

    stage: str
    index: int
    x: np.ndarray
    fitness: np.ndarray
    weights: np.ndarray
    failed: np.ndarray
    best_x: np.ndarray
    best_fitness: float
    n_sims: int
    wall_time: float
    rng_state: str
    extras: dict[str, np.ndarray] = field(default_factory=dict)


IterationCallback = Callable[[Iteration], None]


@dataclass(frozen=True)
class EstimationResult:
    """The outcome of any method or chain, shaped like ``scipy.optimize.OptimizeResult``."""

    method: str
    names: tuple[str, ...]
    x: np.ndarray
    fun: float
    nfev: int
    nit: int
    wall_time: float
    stop_reason: str
    history: tuple[Iteration, ...]
    n_failed: int = 0
    uncertainty: Uncertainty | None = None  # a posterior's, for Bayesian methods
    # the first failed simulations' messages (why each failed: a time-out, a model that
    # asked to terminate before the last measured sample...), as the objective kept them
    failure_messages: tuple[str, ...] = ()

    def best(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.x)}


# --- helpers shared by the methods -------------------------------------------------------


def rng_state(rng: np.random.Generator) -> str:
    """The generator's state as JSON, so the archive can restore it exactly.

    PCG64 keeps 128-bit Python ints (JSON holds them); MT19937 keeps an array, turned into
    a list here.
    """

    def default(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, np.integer):
            return int(o)
        raise TypeError(f"cannot store {type(o).__name__} in an rng state")

    return json.dumps(rng.bit_generator.state, default=default)


def check_option(
    name: str,
    value,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    integer: bool = False,
    allow_none: bool = False,
) -> None:
    """Raise ``ValueError`` naming the option, its value and the allowed range."""
    if value is None and allow_none:
        return
    lo = "" if low is None else f"{low} {'<' if low_open else '<='} "
    hi = "" if high is None else f" {'<' if high_open else '<='} {high}"
    allowed = f"{lo}{name}{hi}" if (lo or hi) else f"a number for {name}"
    kind = "an integer" if integer else "a number"
    if allow_none:
        kind += " or None"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name}={value!r} is not {kind}; allowed: {allowed}")
    if integer and not (isinstance(value, (int, np.integer)) or float(value).is_integer()):
        raise ValueError(f"{name}={value!r} is not an integer; allowed: {allowed}")
    v = float(value)
    bad = (
        not np.isfinite(v)
        or (low is not None and (v <= low if low_open else v < low))
        or (high is not None and (v >= high if high_open else v > high))
    )
    if bad:
        raise ValueError(f"{name}={value!r} is out of range; allowed: {allowed}")


def unit_start(space: SearchSpace, x0) -> np.ndarray | None:
    """``x0`` (physical units) in unit coordinates, or None; rejects points outside the box
    rather than silently moving them."""
    if x0 is None:
        return None
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (space.dim,):
        raise ValueError(f"x0 needs shape ({space.dim},) for {space.names}, got {x0.shape}")
    if not np.all(np.isfinite(x0)) or not space.contains(x0):
        bad = [
            f"{n}={v:g} not in [{lo:g}, {hi:g}]"
            for n, v, lo, hi in zip(space.names, x0, space.lower, space.upper)
            if not lo <= v <= hi
        ]
        raise ValueError(f"x0 is outside the bounds: {', '.join(bad)}")
    return np.clip(space.to_unit(x0), 0.0, 1.0)


def reflect_unit(u: np.ndarray) -> np.ndarray:
    """Fold points back into [0, 1] by mirror reflection at the faces.

    Unlike clipping, reflection keeps a kernel's mass inside the box without piling
    particles onto the bounds. Works for any overshoot (period 2).
    """
    u = np.mod(u, 2.0)
    return np.where(u > 1.0, 2.0 - u, u)


class Tracker:
    """Book-keeping of one method run: evaluates batches, counts simulations and failures,
    keeps the best point, and emits one :class:`Iteration` per iteration to the callback.

    Methods work in unit coordinates; the tracker converts to physical units (clipped to
    the bounds, so round-off in ``from_unit`` never leaves the box) before calling the
    objective. Non-finite fitness counts as a failed evaluation with fitness +inf. The
    best point prefers any successful evaluation to a failed one, then lower fitness,
    then the earlier evaluation.
    """

    def __init__(self, stage: str, objective: Objective, space: SearchSpace,
                 rng: np.random.Generator, callback: IterationCallback | None):
        self.stage, self.objective, self.space = stage, objective, space
        self.rng, self.callback = rng, callback
        self.n_sims = 0
        self.n_failed = 0
        self.best_u = np.full(space.dim, np.nan)
        self.best_f = np.inf
        self.best_failed = True
        self._has_best = False
        self.history: list[Iteration] = []
        self._t0 = time.perf_counter()

    def to_physical(self, U: np.ndarray) -> np.ndarray:
        return self.space.clip(self.space.from_unit(U))

    def evaluate(self, U: np.ndarray) -> Evaluations:
        """Score the rows of ``U`` (unit coordinates, (n, d)) in one objective call."""
        U = self._check(U)
        return self._book(U, self.objective(self.to_physical(U)))

    def evaluate_residuals(self, U: np.ndarray) -> tuple[Evaluations, np.ndarray]:
        """As :meth:`evaluate`, with each row's residual vector (the objective's
        ``residuals``: squares summing to the fitness), for least-squares methods."""
        U = self._check(U)
        residuals = getattr(self.objective, "residuals", None)
        if residuals is None:
            raise ValueError("this objective gives no residual vectors; a least-squares method needs them")
        ev, R = residuals(self.to_physical(U))
        return self._book(U, ev), np.asarray(R, dtype=float)

    def _check(self, U: np.ndarray) -> np.ndarray:
        U = np.asarray(U, dtype=float)
        if U.ndim != 2 or U.shape[1] != self.space.dim or U.shape[0] == 0:
            raise ValueError(f"internal: bad batch shape {U.shape}")
        return U

    def _book(self, U: np.ndarray, ev: Evaluations) -> Evaluations:
        n = U.shape[0]
        fitness = np.asarray(ev.fitness, dtype=float).reshape(-1)
        failed = np.asarray(ev.failed, dtype=bool).reshape(-1)
        rssd = np.asarray(ev.rssd, dtype=float)
        if fitness.shape != (n,) or failed.shape != (n,) or rssd.ndim != 2 or rssd.shape[0] != n:
            raise ValueError(
                f"objective returned fitness {np.shape(ev.fitness)}, rssd {np.shape(ev.rssd)},"
                f" failed {np.shape(ev.failed)} for {n} parameter sets"
            )
        bad = ~np.isfinite(fitness)
        failed = failed | bad
        fitness = np.where(bad, np.inf, fitness)
        self.n_sims += n
        self.n_failed += int(failed.sum())
        ok = ~failed
        pool = np.flatnonzero(ok) if ok.any() else np.arange(n)
        i = pool[np.argmin(fitness[pool])]
        key = (bool(failed[i]), float(fitness[i]))
        if not self._has_best or key < (self.best_failed, self.best_f):
            self.best_u, (self.best_failed, self.best_f) = U[i].copy(), key
            self._has_best = True
        return Evaluations(fitness, rssd, failed)

    @property
    def nit(self) -> int:
        return len(self.history)

    @property
    def best_x(self) -> np.ndarray:
        return self.to_physical(self.best_u)

    def elapsed(self) -> float:
        return time.perf_counter() - self._t0

    def record(self, U, fitness, failed, weights=None, extras=None) -> Iteration:
        """Close one iteration: store it and hand it to the callback."""
        U = np.asarray(U, dtype=float).reshape(-1, self.space.dim)
        n = U.shape[0]
        if weights is None:
            weights = np.full(n, 1.0 / n) if n else np.zeros(0)
        it = Iteration(
            stage=self.stage,
            index=self.nit,
            x=self.to_physical(U),
            fitness=np.asarray(fitness, dtype=float).copy(),
            weights=np.asarray(weights, dtype=float).copy(),
            failed=np.asarray(failed, dtype=bool).copy(),
            best_x=self.best_x,
            best_fitness=self.best_f,
            n_sims=self.n_sims,
            wall_time=self.elapsed(),
            rng_state=rng_state(self.rng),
            extras=dict(extras or {}),
        )
        self.history.append(it)
        if self.callback is not None:
            self.callback(it)
        return it

    def result(self, stop_reason: str, uncertainty: Uncertainty | None = None) -> EstimationResult:
        return EstimationResult(
            method=self.stage,
            names=self.space.names,
            x=self.best_x,
            fun=self.best_f,
            nfev=self.n_sims,
            nit=self.nit,
            wall_time=self.elapsed(),
            stop_reason=stop_reason,
            history=tuple(self.history),
            n_failed=self.n_failed,
            uncertainty=uncertainty,
        )


def initial_population(space: SearchSpace, n: int, rng: np.random.Generator, x0=None) -> np.ndarray:
    """``n`` uniform points in unit coordinates; a given ``x0`` replaces the first, so that a
    chain's second stage starts from where the first ended."""
    U = rng.uniform(size=(n, space.dim))
    u0 = unit_start(space, x0)
    if u0 is not None:
        U[0] = u0
    return U
