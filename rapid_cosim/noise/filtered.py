"""Noise that another recorder's noise makes after a known linear filter, and the
whitening of a noise given only by its autocovariance.

Why: a plant's electrical power is compared with a bench whose input is the ROCOF
derived from the recorded frequency (:mod:`rapid_cosim.simulator.rocof`). The frequency
recorder's noise, passed through that derivative filter and scaled by 2 H / f_nom, is in
every P_e residual, and it is band-pass: its autocorrelation is positive over a few
samples and negative over the filter's window, then zero. White noise plus slow
Ornstein-Uhlenbeck parts (:class:`~.model.RecorderNoise`) cannot represent that; a null
or a whitening that treats it as slow noise leaves correlation that an adequacy test then
calls misfit (on ANDES events, 4 of 10 structure verdicts on P_e were "unexplained"
where P_m gave the generating structure).

:class:`FilteredNoise` is such a component: a source noise model (the frequency
recorder's, fitted to its quiet samples) and the filter's taps (scale included). Its
autocovariance is exact: ``gamma_y(k) = sum_m c(m) gamma_x(k + m)`` with ``c`` the taps'
own autocorrelation.

:class:`LevinsonWhitener` whitens any stationary noise from its autocovariance by the
Durbin-Levinson recursion: the exact one-step predictions of the first ``p`` samples of a
run, then the order-``p`` predictor, ``p`` the order at which the partial correlations
have died out (below 1e-9 for a run of orders, at most ``MAX_ORDER``). It has the
interface of :class:`~.model.Whitener`, against which the tests check it on the models
both can whiten, and a dense Cholesky factor on those only it can.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from scipy import signal

from .band import Triangular
from .runs import RunWhitening



class StationaryNoise(Protocol):
    """What a filtered part and the Levinson whitener need of a noise (a
    :class:`~.model.RecorderNoise` is one): named here so that this module does not import
    the model that holds it (model -> filtered, one way)."""

    @property
    def dt(self) -> float: ...

    def autocovariance(self, lags: np.ndarray) -> np.ndarray: ...

    def sample(self, times: np.ndarray, rng: np.random.Generator, size: int | None = None) -> np.ndarray: ...

    def describe(self) -> str: ...

MAX_ORDER = 800  # samples: 27 s at 30 frames/s, beyond any slow component a window can estimate
_PACF_TOL = 1e-9  # partial correlations smaller than this for _QUIET_ORDERS orders in a row: converged
_QUIET_ORDERS = 8


@dataclass(frozen=True)
class FilteredNoise:
    """``taps`` (scale included) applied to noise ``source``, on ``source``'s grid."""

    source: StationaryNoise
    taps: tuple[float, ...]

    def __post_init__(self):
        taps = tuple(float(c) for c in self.taps)
        if not taps or not all(math.isfinite(c) for c in taps) or not any(taps):
            raise ValueError("a filtered noise needs finite taps, not all zero")
        object.__setattr__(self, "taps", taps)

    @property
    def dt(self) -> float:
        return self.source.dt

    def autocovariance(self, lags: np.ndarray) -> np.ndarray:
        """Covariance at integer ``lags`` (samples of ``dt``)."""
        h = np.asarray(self.taps)
        c = np.correlate(h, h, mode="full")  # c[m + L - 1] = sum_i h_i h_{i+m}, m = -(L-1)..L-1
        m = np.arange(-(h.size - 1), h.size)
        lags = np.abs(np.asarray(lags, dtype=float))
        return np.array([float(c @ self.source.autocovariance(k + m)) for k in lags.ravel()]).reshape(lags.shape)

    @property
    def sigma(self) -> float:
        return float(math.sqrt(self.autocovariance(np.array([0]))[0]))

    def sample(self, n: int, rng: np.random.Generator, rows: int) -> np.ndarray:
        """``(rows, n)`` draws on a regular grid of ``dt`` (the process is stationary, so
        a recorder's jitter changes nothing the whitening sees)."""
        L = len(self.taps)
        x = self.source.sample(np.arange(n + L - 1) * self.dt, rng, rows)
        return signal.lfilter(np.asarray(self.taps), [1.0], x, axis=1)[:, L - 1:]

    def describe(self) -> str:
        return f"filtered {self.sigma:.3g} ({len(self.taps)} taps on {self.source.describe()})"


@dataclass(eq=False)
class LevinsonWhitener(RunWhitening):
    """The innovations map of a stationary noise from its autocovariance (module
    docstring); ``s`` holds the innovation variances of the first ``m`` samples of a run,
    ``s_inf`` the variance after them."""

    model: StationaryNoise
    m: int = field(init=False)
    s: np.ndarray = field(init=False)
    s_inf: float = field(init=False)

    def __post_init__(self):
        gamma = self.model.autocovariance(np.arange(MAX_ORDER + 1))
        phi = np.zeros(0)
        rows, v = [], [float(gamma[0])]
        quiet = 0
        for k in range(1, MAX_ORDER + 1):
            rows.append(phi)
            kappa = (gamma[k] - phi @ gamma[k - 1:0:-1]) / v[-1] if k > 1 else gamma[1] / v[-1]
            phi = np.concatenate([phi - kappa * phi[::-1], [kappa]])
            v.append(v[-1] * (1.0 - kappa * kappa))
            quiet = quiet + 1 if abs(kappa) < _PACF_TOL else 0
            if quiet >= _QUIET_ORDERS:
                break
        self.m = len(rows)
        self.s, self.s_inf = np.array(v[:self.m]), float(v[self.m])
        W = np.eye(self.m)  # row t: y_t minus its prediction from the t samples before it
        for t, coef in enumerate(rows):
            W[t, t - coef.size:t] = -coef[::-1]
        self._T = Triangular(W / np.sqrt(self.s)[:, None])
        self._a = np.concatenate([[1.0], -phi])  # the order-m predictor's error filter

    def whiten_runs(self, y: np.ndarray) -> np.ndarray:
        """Standardised innovations of gap-free runs ``y`` (rows, n)."""
        y = np.atleast_2d(np.asarray(y, dtype=float))
        n, m = y.shape[1], self.m
        if n <= m:
            return self._T.apply(y)
        e = np.empty_like(y)
        e[:, :m] = self._T.apply(y[:, :m])
        e[:, m:] = signal.lfilter(self._a, [1.0], y, axis=1)[:, m:] / math.sqrt(self.s_inf)
        return e
