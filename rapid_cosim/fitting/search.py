"""What a problem and its estimators exchange: the box searched and the scores of a batch.

A leaf module (it imports nothing from the package), so that the problem definition and
the evaluator can use these types without reaching down the chain to the estimators.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SearchSpace:
    """Names and box bounds of the estimated parameters.

    Methods work in unit coordinates (each parameter scaled to [0, 1] by its bounds), so
    that a droop of 0.05 and a time constant of 10 s are moved on the same footing.
    Parameters flagged in ``log`` are scaled by their logarithm: a rate that matters
    anywhere between 0.001 and 0.2 pu/s gets as much of a uniform prior, a swarm or a
    simplex step per decade as per unit of the others.
    """

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    log: tuple[bool, ...] | None = None

    def __post_init__(self):
        lower = np.asarray(self.lower, dtype=float)
        upper = np.asarray(self.upper, dtype=float)
        if lower.shape != (len(self.names),) or upper.shape != lower.shape:
            raise ValueError("lower and upper need one entry per name")
        if not np.all(upper > lower):
            bad = [n for n, lo, hi in zip(self.names, lower, upper) if not hi > lo]
            raise ValueError(f"upper bound must exceed lower bound for {bad}")
        log = tuple(bool(v) for v in self.log) if self.log is not None else (False,) * len(self.names)
        if len(log) != len(self.names):
            raise ValueError("log needs one flag per name")
        bad = [n for n, lo, flag in zip(self.names, lower, log) if flag and not lo > 0]
        if bad:
            raise ValueError(f"a log scale needs a positive lower bound: {bad}")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(self, "log", log)
        mask = np.array(log, dtype=bool)
        object.__setattr__(self, "_mask", mask)
        object.__setattr__(self, "_lo", np.where(mask, np.log(np.where(mask, lower, 1.0)), lower))
        object.__setattr__(self, "_hi", np.where(mask, np.log(np.where(mask, upper, 1.0)), upper))

    @property
    def dim(self) -> int:
        return len(self.names)

    @property
    def width(self) -> np.ndarray:
        return self.upper - self.lower

    def to_unit(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if self._mask.any():
            x = np.where(self._mask, np.log(np.where(self._mask, np.maximum(x, self.lower), 1.0)), x)
        return (x - self._lo) / (self._hi - self._lo)

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        v = self._lo + np.asarray(u, dtype=float) * (self._hi - self._lo)
        if self._mask.any():
            v = np.where(self._mask, np.exp(v), v)
        return v

    def clip(self, x: np.ndarray) -> np.ndarray:
        return np.clip(x, self.lower, self.upper)

    def stepped(self, u: np.ndarray, step: float, free: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(points, steps): the unit point ``u`` and ``u`` stepped by ``step`` along each
        coordinate (backward where forward leaves the box; 0 where ``free`` holds it),
        mapped back and clipped: the batch every forward-difference Jacobian is read from,
        as ``(f(points[1:]) - f(points[0])) / steps``."""
        u = np.asarray(u, dtype=float)
        steps = np.where(u + step <= 1.0, step, -step)
        if free is not None:
            steps = steps * free
        U = np.tile(u, (self.dim + 1, 1))
        U[1:][np.arange(self.dim), np.arange(self.dim)] += steps
        return self.clip(self.from_unit(U)), steps

    def contains(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        return np.all((x >= self.lower) & (x <= self.upper), axis=-1)


@dataclass(frozen=True)
class Evaluations:
    """Scores of a batch of parameter sets, in the order they were given.

    ``fitness`` is what is minimised (RSSD, or ARSSD over experiments); ``rssd`` keeps
    the per-experiment values (n, E) that a likelihood needs; ``failed`` marks
    simulations that did not finish and carry a penalty fitness instead.
    """

    fitness: np.ndarray
    rssd: np.ndarray
    failed: np.ndarray

    @classmethod
    def from_fitness(cls, fitness: np.ndarray) -> "Evaluations":
        """For objectives with one experiment and no failures (analytic test functions)."""
        f = np.asarray(fitness, dtype=float)
        return cls(f, f[:, None].copy(), np.zeros(f.shape, dtype=bool))
