"""A recorder's noise: white measurement noise plus slow correlated components.

Real transducers and plants add two kinds of noise to a recorded power: white noise
(quantisation, the A/D converter, electrical pick-up) and slow wander with a correlation
time of seconds (the transducer's filter, turbulence, the plant's own small moves). Their
sum is not an AR(1) process: its autocorrelation drops at lag 1 (the white part) and then
decays slowly (the slow part), as the field tests' quiet windows show. One AR(1) cannot
represent that, and prewhitening with it leaves correlation a whiteness test then calls
misfit.

:class:`RecorderNoise` is white noise ``sigma_white`` plus ``K`` Ornstein-Uhlenbeck
components ``(sigma_k, tau_k)`` in continuous time (an OU component sampled at interval
``dt`` is AR(1) with ``phi = exp(-dt / tau)``; white + one OU is ARMA(1,1)). Continuous
time, so that samples with jittered time stamps are simulated exactly.

Whitening is the Kalman filter's innovations, standardised: for a residual ``r`` on a
regular grid it returns ``eps = L^-1 r`` with ``Cov(r) = L L^T``, so that ``sum eps^2`` is
the Gaussian likelihood's quadratic form. It is a fixed linear map (the gains do not
depend on the data), built once per model and sample interval (:class:`Whitener`): the
first ``m`` samples, while the gains still change, as a dense triangular matrix; the rest
with the steady-state filter through :func:`scipy.signal.lfilter`, plus the free
response of the state reached at sample ``m``. Rows of a batch (parameter sets, bootstrap
replicates) are whitened together; each contiguous run of valid samples starts from the
stationary prior (a gap breaks the chain).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import linalg, signal

from .filtered import FilteredNoise, LevinsonWhitener
from .band import Triangular
from .runs import RunWhitening, rowwise

FAMILIES = ("white", "ar1", "white+ar1", "white+2ar1")
_GAIN_TOL = 1e-13  # the gains have converged when they change less than this (relative)
_MAX_TRANSIENT = 300  # samples; past this the steady-state filter is used (gains within rho^600 of it)


@dataclass(frozen=True)
class RecorderNoise:
    """White noise plus Ornstein-Uhlenbeck components, on a recorder of interval ``dt``.

    ``sigma_white``: standard deviation of the white part (0 for a pure AR family);
    ``components``: ``(sigma, tau)`` pairs, standard deviation and correlation time (s)
    of each slow part, slowest last; ``dt``: the nominal sample interval (s) whitening
    assumes (the recorder's median interval).
    """

    sigma_white: float
    components: tuple[tuple[float, float], ...] = ()
    dt: float = 0.1
    filtered: tuple[FilteredNoise, ...] = ()  # other noises through known filters (not estimated here)

    def __post_init__(self):
        comps = tuple((float(s), float(t)) for s, t in self.components)
        object.__setattr__(self, "components", tuple(sorted(comps, key=lambda c: c[1])))
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise ValueError(f"dt must be a positive number of seconds, got {self.dt!r}")
        if not (self.sigma_white >= 0 and math.isfinite(self.sigma_white)):
            raise ValueError(f"sigma_white must be >= 0, got {self.sigma_white!r}")
        for s, t in comps:
            if not (s > 0 and math.isfinite(s)) or not (t > 0 and math.isfinite(t)):
                raise ValueError(f"a slow component needs sigma > 0 and tau > 0 (s), got sigma={s!r}, tau={t!r}")
        if self.sigma_white == 0 and not comps:
            raise ValueError("a noise model needs a white part or a slow component")
        for f in self.filtered:
            if abs(f.dt - self.dt) > 0.01 * self.dt:
                raise ValueError(f"a filtered component on a {f.dt:g} s grid cannot join noise sampled every "
                                 f"{self.dt:g} s")

    @property
    def family(self) -> str:
        k = len(self.components)
        if k == 0:
            return "white"
        if self.sigma_white == 0:
            return "ar1" if k == 1 else f"{k}ar1"
        return "white+ar1" if k == 1 else f"white+{k}ar1"

    @property
    def sigma(self) -> float:
        """Standard deviation of the whole noise."""
        return float(math.sqrt(self.autocovariance(np.array([0]))[0]))

    def autocovariance(self, lags: np.ndarray, dt: float | None = None) -> np.ndarray:
        """Covariance at integer ``lags`` of samples ``dt`` apart (default the model's;
        a filtered component exists on its own grid only)."""
        dt = self.dt if dt is None else dt
        lags = np.asarray(lags, dtype=float)
        cov = sum(s * s * np.exp(-np.abs(lags) * dt / t) for s, t in self.components) if self.components \
            else np.zeros_like(lags)
        cov = cov + np.where(lags == 0, self.sigma_white ** 2, 0.0)
        if self.filtered and abs(dt - self.dt) > 0.01 * self.dt:
            raise ValueError(f"the filtered components are defined every {self.dt:g} s, not every {dt:g} s")
        return cov + sum(f.autocovariance(lags) for f in self.filtered)

    def autocorrelation(self, lags: np.ndarray, dt: float | None = None) -> np.ndarray:
        """Autocorrelation at integer ``lags`` of samples ``dt`` apart (default the model's)."""
        return self.autocovariance(lags, dt) / self.sigma ** 2

    def innovation_sigma(self) -> float:
        """Standard deviation of the one-step prediction error once the filter has settled:
        the level a prewhitened residual of a perfect model has."""
        return float(math.sqrt(self.whitener().s_inf))

    def with_dt(self, dt: float) -> "RecorderNoise":
        return RecorderNoise(self.sigma_white, self.components, dt, self.filtered)

    def whitener(self) -> "Whitener":
        return _whitener(self)

    def whiten(self, residual: np.ndarray) -> np.ndarray:
        """Standardised innovations of ``residual`` ((n,) or (rows, n)); NaN samples are
        gaps, each valid run whitened from the stationary prior. Returns the same shape
        with NaN where the input is NaN."""
        return self.whitener().whiten_masked(residual)

    def sample(self, times: np.ndarray, rng: np.random.Generator, size: int | None = None) -> np.ndarray:
        """Noise at the given (possibly irregular) ``times``: ``(n,)``, or ``(size, n)``
        replicates. The OU components are simulated exactly between time stamps."""
        t = np.asarray(times, dtype=float)
        rows = 1 if size is None else int(size)
        out = self.sigma_white * rng.standard_normal((rows, t.size))
        if self.components:
            dt = np.diff(t)
            for s, tau in self.components:
                z = rng.standard_normal((rows, t.size))
                out += _ou_paths(np.exp(-dt / tau)[:, None], np.array([s]), z.T).T
        for f in self.filtered:
            out += f.sample(t.size, rng, rows)
        return out[0] if size is None else out

    # -- parameters as a vector (log scale), for estimation and its uncertainty

    def log_parameters(self) -> np.ndarray:
        v = [] if self.sigma_white == 0 else [math.log(self.sigma_white)]
        for s, t in self.components:
            v += [math.log(s), math.log(t)]
        return np.array(v)

    @classmethod
    def from_log_parameters(cls, family: str, theta: np.ndarray, dt: float) -> "RecorderNoise":
        theta = np.asarray(theta, dtype=float)
        white = family.startswith("white")
        k = n_components(family)
        sigma_white = float(np.exp(theta[0])) if white else 0.0
        rest = theta[1:] if white else theta
        comps = tuple((float(np.exp(rest[2 * j])), float(np.exp(rest[2 * j + 1]))) for j in range(k))
        return cls(sigma_white, comps, dt)

    def to_config(self) -> dict:
        """As a config's ``[noise.<output>]`` table."""
        out: dict = {"white": self.sigma_white, "dt": self.dt}
        if self.components:
            out["components"] = [{"sigma": s, "tau": t} for s, t in self.components]
        return out

    @classmethod
    def from_config(cls, table: dict) -> "RecorderNoise":
        comps = tuple((float(c["sigma"]), float(c["tau"])) for c in table.get("components", []))
        return cls(float(table.get("white", 0.0)), comps, float(table["dt"]))

    def describe(self) -> str:
        parts = [f"white {self.sigma_white:.3g}"] if self.sigma_white > 0 else []
        parts += [f"slow {s:.3g} (tau {t:.3g} s, phi {math.exp(-self.dt / t):.3f} per sample)"
                  for s, t in self.components]
        parts += [f.describe() for f in self.filtered]
        return " + ".join(parts) + f" pu at {self.dt:g} s"


def sample_draws(models: "list[RecorderNoise]", times: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One replicate of noise per model (all of one family), at the given times:
    ``(len(models), n)``; what a bootstrap over the noise estimate's uncertainty needs."""
    t = np.asarray(times, dtype=float)
    rows = len(models)
    white = np.array([m.sigma_white for m in models])
    out = white[:, None] * rng.standard_normal((rows, t.size))
    k = len(models[0].components)
    if any(len(m.components) != k for m in models):
        raise ValueError("sample_draws needs models of one family")
    dt = np.diff(t)
    for j in range(k):
        s = np.array([m.components[j][0] for m in models])
        tau = np.array([m.components[j][1] for m in models])
        out += _ou_paths(np.exp(-dt[:, None] / tau[None, :]), s, rng.standard_normal((t.size, rows))).T
    if any(m.filtered != models[0].filtered for m in models):
        raise ValueError("sample_draws needs models with the same filtered components")
    for f in models[0].filtered:
        out += f.sample(t.size, rng, rows)
    return out


def _ou_paths(a: np.ndarray, s: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Ornstein-Uhlenbeck paths, exact between irregular stamps: ``x_0 = s z_0``,
    ``x_k = a_k x_{k-1} + s sqrt(1 - a_k^2) z_k``, time first (``z`` (n, rows); ``a``
    (n - 1, rows or 1), the decay over each step; ``s`` (rows or 1), the stationary std).
    The steps' decays differ, so no fixed filter runs it: one pass over time, each step
    vectorised over the paths (the only loop of the kind in noise/)."""
    b = s * np.sqrt(1.0 - a * a)
    x = np.empty_like(z)
    x[0] = s * z[0]
    for k in range(1, z.shape[0]):
        x[k] = a[k - 1] * x[k - 1] + b[k - 1] * z[k]
    return x


def n_components(family: str) -> int:
    if family not in FAMILIES:
        raise ValueError(f"unknown noise family {family!r}; choose one of {', '.join(FAMILIES)}")
    return {"white": 0, "ar1": 1, "white+ar1": 1, "white+2ar1": 2}[family]


@functools.lru_cache(maxsize=64)
def _whitener(model: RecorderNoise) -> "Whitener | LevinsonWhitener":
    if model.filtered:  # no small state space: whitened from the autocovariance
        return LevinsonWhitener(model)
    return Whitener(model)


@dataclass(eq=False)
class Whitener(RunWhitening):
    """The exact innovations map of a :class:`RecorderNoise` on a regular grid (see the
    module docstring); ``s`` holds the innovation variances of the first ``m`` samples,
    ``s_inf`` the steady one."""

    model: RecorderNoise
    m: int = field(init=False)
    s: np.ndarray = field(init=False)
    s_inf: float = field(init=False)

    def __post_init__(self):
        mdl = self.model
        k = len(mdl.components)
        if k == 0:
            self.m, self.s, self.s_inf = 0, np.zeros(0), mdl.sigma_white ** 2
            return
        sig = np.array([s for s, _ in mdl.components])
        phi = np.exp(-mdl.dt / np.array([t for _, t in mdl.components]))
        F = np.diag(phi)
        Q = np.diag(sig ** 2 * (1 - phi ** 2))
        H = np.ones(k)
        R = mdl.sigma_white ** 2
        P = _steady_prediction_covariance(F, Q, R, sig)
        S_inf = float(H @ P @ H) + R
        K_inf = P @ H / S_inf
        self._Fs = F @ (np.eye(k) - np.outer(K_inf, H))
        Gs = F @ K_inf
        lam, V = np.linalg.eig(self._Fs)
        rho = float(np.max(np.abs(lam)))
        # the gains approach K_inf like rho^(2j): the first m samples are whitened exactly
        m = 1 if rho < 1e-8 else int(min(math.ceil(math.log(_GAIN_TOL) / (2 * math.log(rho))) + 1, _MAX_TRANSIENT))
        # exact for them: the Cholesky factor of their covariance (eps = L^-1 y standardised)
        lag = np.abs(np.subtract.outer(np.arange(m), np.arange(m)))
        cov = R * np.eye(m) + sum(s * s * p ** lag for s, p in zip(sig, phi))
        L = np.linalg.cholesky(cov)
        self.m, self.s, self.s_inf = m, np.diag(L) ** 2, S_inf
        self._T = Triangular(linalg.solve_triangular(L, np.eye(m), lower=True))  # standardised: eps[:m] = W @ y[:m]
        # the prediction of the states at sample m from the first m samples: x = M @ y[:m]
        cross = (sig ** 2)[:, None] * phi[:, None] ** (m - np.arange(m))[None, :]  # Cov(x_m, y_i)
        self._M = linalg.cho_solve((L, True), cross.T).T
        b, a = signal.ss2tf(self._Fs, Gs[:, None], -H[None, :], np.array([[1.0]]))
        self._b, self._a = np.asarray(b[0], dtype=float), np.asarray(a, dtype=float)
        # free response -H Fs^j of the steady filter from the state at sample m, by Fs's eigenvalues
        n_free = 1 if rho < 1e-12 else int(min(math.ceil(math.log(1e-16) / math.log(rho)) + 1, 20 * _MAX_TRANSIENT))
        powers = lam[None, :] ** np.arange(n_free)[:, None]
        self._free = np.real(((-H @ V)[None, :] * powers) @ np.linalg.inv(V))  # (L, k)

    def whiten_runs(self, y: np.ndarray) -> np.ndarray:
        """Standardised innovations of gap-free runs ``y`` (rows, n), each from the
        stationary prior."""
        y = np.atleast_2d(np.asarray(y, dtype=float))
        if not self.model.components:
            return y / self.model.sigma_white
        n, m = y.shape[1], self.m
        if n <= m:
            return self._T.apply(y)
        e = np.empty_like(y)
        e[:, :m] = self._T.apply(y[:, :m])
        state = rowwise(y[:, :m], self._M)  # (rows, k)
        rest = signal.lfilter(self._b, self._a, y[:, m:], axis=1)
        L = min(n - m, self._free.shape[0])
        rest[:, :L] += rowwise(state, self._free[:L])
        e[:, m:] = rest / math.sqrt(self.s_inf)
        return e

def _steady_prediction_covariance(F, Q, R, sig) -> np.ndarray:
    """The Kalman filter's steady one-step prediction covariance: in closed form for one
    component (a scalar quadratic), by scipy's Riccati solver otherwise."""
    if F.shape[0] == 1:
        f2, q = float(F[0, 0]) ** 2, float(Q[0, 0])
        if R == 0:
            return np.array([[q]])
        # P = f2 P R / (P + R) + q  <=>  P^2 + (R (1 - f2) - q) P - q R = 0
        b = R * (1 - f2) - q
        return np.array([[0.5 * (-b + math.sqrt(b * b + 4 * q * R))]])
    return linalg.solve_discrete_are(F.T, np.ones((F.shape[0], 1)), Q,
                                     np.array([[max(R, 1e-12 * float(sig @ sig))]]))
