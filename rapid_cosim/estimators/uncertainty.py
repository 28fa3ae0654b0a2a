"""What the data say about the estimated parameters, however it was found: a centre, a
covariance and intervals at a level.

One type for both ways the package gets there: weighted samples of a posterior (SMC)
with :meth:`Uncertainty.from_samples`, and the Hessian of the negative log-likelihood at
an optimum (Laplace's method) with :meth:`Uncertainty.from_hessian`. Reports take it as
an object; the fields that only one way has (samples, the Hessian) are None otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import stats


def weighted_quantile(x: np.ndarray, w: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Quantiles of a weighted sample: the smallest x whose weighted CDF reaches q.

    Unlike interpolating rules, this inverse CDF gives the same answer for a particle of
    weight 2w as for two copies of weight w, so resampling does not shift the interval.
    """
    order = np.argsort(x, kind="stable")
    xs, ws = x[order], w[order]
    cdf = np.cumsum(ws) / ws.sum()
    return xs[np.searchsorted(cdf, q, side="left").clip(0, xs.size - 1)]


def _inverse(H: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return np.full_like(H, np.nan)


@dataclass(frozen=True)
class Uncertainty:
    """``interval`` is (d, 2), equal-tailed at ``level``; ``method`` says how it was found
    (``"samples"`` or ``"hessian"``); ``evaluations`` counts the objective calls it cost
    beyond the estimation (a Hessian's stencil)."""

    names: tuple[str, ...]
    mean: np.ndarray
    cov: np.ndarray
    interval: np.ndarray
    level: float
    method: str
    samples: np.ndarray | None = None
    weights: np.ndarray | None = None
    log_evidence: float | None = None
    hessian: np.ndarray | None = None  # of the negative log-likelihood, physical units
    steps: np.ndarray | None = None  # the Hessian's finite-difference steps, physical units
    evaluations: int = 0
    at_bound: tuple[str, ...] = ()  # parameters at a bound, whose stencil was moved inside

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    @property
    def corr(self) -> np.ndarray:
        s = self.std
        with np.errstate(invalid="ignore", divide="ignore"):
            c = self.cov / np.outer(s, s)
        c = np.nan_to_num(c)
        np.fill_diagonal(c, 1.0)
        return c

    def intervals(self) -> dict[str, tuple[float, float]]:
        return {n: (float(lo), float(hi)) for n, (lo, hi) in zip(self.names, self.interval)}

    @classmethod
    def from_samples(cls, names, samples: np.ndarray, weights: np.ndarray, *, level: float = 0.9,
                     log_evidence: float | None = None) -> "Uncertainty":
        """Weighted mean, covariance and equal-tailed quantile intervals of a sample."""
        samples = np.asarray(samples, dtype=float)
        w = np.asarray(weights, dtype=float)
        w = w / w.sum()
        mean = w @ samples
        dev = samples - mean
        cov = (w[:, None] * dev).T @ dev
        q = np.array([(1 - level) / 2, (1 + level) / 2])
        interval = np.array([weighted_quantile(samples[:, j], w, q) for j in range(samples.shape[1])])
        return cls(tuple(names), mean, cov, interval, float(level), "samples", samples.copy(), w.copy(),
                   None if log_evidence is None else float(log_evidence))

    @classmethod
    def from_hessian(cls, names, x: np.ndarray, hessian: np.ndarray, *, level: float = 0.9,
                     steps: np.ndarray | None = None, evaluations: int = 0,
                     at_bound: tuple[str, ...] = ()) -> "Uncertainty":
        """A Gaussian centred at ``x`` whose covariance is the inverse Hessian."""
        x = np.asarray(x, dtype=float)
        hessian = np.asarray(hessian, dtype=float)
        cov = _inverse(hessian)
        return cls(tuple(names), x, cov, _gaussian_interval(x, cov, level), float(level), "hessian",
                   hessian=hessian, steps=steps, evaluations=int(evaluations), at_bound=tuple(at_bound))

    def scaled(self, factor: float) -> "Uncertainty":
        """The covariance times ``factor`` (e.g. AR(1) noise's inflation), intervals widened
        by its square root about the centre."""
        half = np.sqrt(factor) * (self.interval - self.mean[:, None])
        return replace(self, cov=self.cov * factor, interval=self.mean[:, None] + half,
                       hessian=None if self.hessian is None else self.hessian / factor)

    def to_json(self) -> dict:
        out = {"names": list(self.names), "mean": self.mean.tolist(), "cov": self.cov.tolist(),
               "interval": self.interval.tolist(), "level": self.level, "method": self.method,
               "log_evidence": self.log_evidence, "evaluations": self.evaluations, "at_bound": list(self.at_bound)}
        for key in ("hessian", "steps"):
            value = getattr(self, key)
            out[key] = None if value is None else np.asarray(value).tolist()
        return out

    @classmethod
    def from_json(cls, d: dict) -> "Uncertainty":
        arr = (lambda v: None if v is None else np.array(v, dtype=float))  # noqa: E731
        return cls(tuple(d["names"]), arr(d["mean"]), arr(d["cov"]), arr(d["interval"]), float(d["level"]),
                   d["method"], log_evidence=d.get("log_evidence"), hessian=arr(d.get("hessian")),
                   steps=arr(d.get("steps")), evaluations=int(d.get("evaluations", 0)),
                   at_bound=tuple(d.get("at_bound", ())))


def _gaussian_interval(x: np.ndarray, cov: np.ndarray, level: float) -> np.ndarray:
    z = stats.norm.ppf(0.5 + level / 2)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return np.column_stack([x - z * sd, x + z * sd])
