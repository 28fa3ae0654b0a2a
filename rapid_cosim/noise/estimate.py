"""The recorder's noise model from its quiet stretches, with the estimate's own uncertainty.

Each family of :data:`~.model.FAMILIES` (white; AR(1); white + AR(1), i.e. ARMA(1,1);
white + two AR(1) components) is fitted by restricted maximum likelihood (REML) over all
quiet stretches of one recorder at once: each stretch is whitened exactly (the Kalman
innovations of :mod:`.model`) together with its trend regressors, the trend is profiled
out by generalised least squares, and the REML term ``log |X' S^-1 X|`` corrects the
variance for what the trends absorbed. The family with the lowest BIC is kept.

Uncertainty: the inverse of the numerical Hessian of the REML deviance in the log
parameters, so that :meth:`NoiseFit.draw` gives noise models as plausible as the data
allow, which the adequacy null (:mod:`rapid_cosim.diagnose.adequacy`) draws from.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Protocol, Sequence

import numpy as np
from scipy import optimize


from ..errors import DataError
from .model import FAMILIES, RecorderNoise, n_components
from .quiet import QuietStretch, Recorded, quiet_stretches, recorder_groups


class Mapper(Protocol):
    """What computes a function over chunks elsewhere, results in the chunks' order (a
    local engine of :mod:`rapid_cosim.fitting.engine`, made by the caller: this layer
    imports none)."""

    def map(self, fn: Callable[[Any, np.ndarray], Any], payload: Any, chunks: Sequence[np.ndarray]) -> list: ...

LAGS = 12  # autocorrelation lags reported against the model's
DRAW_FACTOR = 3.0  # noise models drawn for the adequacy null stay within this factor of the estimate


@dataclass(frozen=True, eq=False)
class NoiseFit:
    """One recorder's noise model, fitted to its quiet stretches.

    ``covariance``: of the log parameters (:meth:`RecorderNoise.log_parameters`);
    ``families``: BIC of every family tried; ``acf``/``acf_model``: the stretches'
    autocorrelation at lags 1..:data:`LAGS` (detrended, pooled) and what the model
    predicts for the same detrended stretches."""

    model: RecorderNoise
    covariance: np.ndarray
    tests: tuple[str, ...]
    n_samples: int
    n_stretches: int
    deviance: float
    families: dict[str, float]
    acf: np.ndarray = field(repr=False)
    acf_model: np.ndarray = field(repr=False)
    stretches: tuple[tuple[str, str, float, float], ...] = field(default=(), repr=False)
    # The richest family fitted, when BIC chose a poorer one: the adequacy null draws from
    # it (see draw), since a component too small for the quiet data to select can still
    # show in a whole test's Ljung-Box.
    richest: tuple[RecorderNoise, np.ndarray] | None = field(default=None, repr=False)
    # Each fitted family's REML deviance over the stretches, for draws from the likelihood
    # itself (see draw); None for a model taken as known.
    likelihoods: Mapping[str, "Likelihood"] = field(default_factory=dict, repr=False)

    @property
    def family(self) -> str:
        return self.model.family

    @classmethod
    def known(cls, model: RecorderNoise, tests: Sequence[str] = ()) -> "NoiseFit":
        """A noise model taken as known (stated by its user, or a test's truth): no
        uncertainty, no quiet data behind it."""
        k = model.log_parameters().size
        lags = np.arange(1, LAGS + 1)
        return cls(model, np.zeros((k, k)), tuple(tests), 0, 0, float("nan"), {}, model.autocorrelation(lags),
                   model.autocorrelation(lags))

    def standard_errors(self) -> np.ndarray:
        """Relative standard errors of the parameters (log scale: ~ relative)."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def draw(self, rng: np.random.Generator, size: int, mapper: Mapper | None = None) -> list[RecorderNoise]:
        """Noise models as plausible as the quiet data allow: drawn from the REML
        likelihood itself (sampling-importance-resampling from a Student-t proposal
        around the estimate, twice as wide as its Hessian says), where the fit kept it.

        Why the likelihood and not its quadratic approximation: 10 s of pre-event data at
        30 frames/s hold a slow component's correlation time poorly and lopsidedly. One
        draw put it at 0.18 s where the recorder's was 0.65 s (5.6 units of deviance
        away, a normal approximation's 3 standard deviations, beyond its old truncation
        at a factor 3); the true model's residual, whitened by that estimate, then failed
        Ljung-Box at p 0.0007 while the null had no replicate like it. The draws come
        from the richest family fitted (``richest``) where BIC chose a poorer one: the
        null then covers the family choice too (on 100 effect-free study campaigns, a
        slow component a third of the white noise's size, which the quiet data could not
        select, failed Ljung-Box on whole tests of a campaign whose null was white).
        Without a likelihood (a model taken as known, or an old fit), the normal
        approximation truncated at a factor :data:`DRAW_FACTOR`, as before. ``mapper``:
        where the proposals' deviances are computed (:meth:`Likelihood.deviances`)."""
        model, cov = self.richest if self.richest is not None else (self.model, self.covariance)
        theta = model.log_parameters()
        cov = 0.5 * (cov + cov.T)
        if not np.all(np.isfinite(cov)):
            cov = np.diag(np.full(theta.size, (math.log(DRAW_FACTOR) / 2) ** 2))
        likelihood = self.likelihoods.get(model.family)
        if likelihood is not None and theta.size:
            return likelihood.draw(theta, cov, rng, size, mapper)
        draws = rng.multivariate_normal(theta, cov, size=size, method="eigh")
        draws = np.clip(draws, theta - math.log(DRAW_FACTOR), theta + math.log(DRAW_FACTOR))
        return [RecorderNoise.from_log_parameters(model.family, d, model.dt) for d in draws]

    def to_json(self) -> dict:
        names = ["sigma_white"] if self.model.sigma_white > 0 else []
        for k in range(len(self.model.components)):
            names += [f"sigma_{k + 1}", f"tau_{k + 1}"]
        values = np.exp(self.model.log_parameters())
        return {"family": self.family, "model": self.model.to_config(), "description": self.model.describe(),
                "parameters": {n: {"value": float(v), "relative_se": float(se)}
                               for n, v, se in zip(names, values, self.standard_errors())},
                "tests": list(self.tests), "samples": self.n_samples, "stretches": self.n_stretches,
                "bic": self.families, "acf": self.acf.tolist(), "acf_model": self.acf_model.tolist()}


def _deviance(model: RecorderNoise, batches) -> float:
    """REML deviance (-2 log L, constants dropped) over stretches grouped by length."""
    w = model.whitener()
    total = 0.0
    for y, X in batches:  # y: (s, n), X: (s, n, q)
        s, n, q = X.shape
        stacked = np.concatenate([y[:, None, :], np.transpose(X, (0, 2, 1))], axis=1).reshape(s * (1 + q), n)
        z = w.whiten_runs(stacked).reshape(s, 1 + q, n)
        ey, eX = z[:, 0], z[:, 1:]
        XtX = np.einsum("sqn,srn->sqr", eX, eX)
        Xty = np.einsum("sqn,sn->sq", eX, ey)
        beta = np.linalg.solve(XtX, Xty[..., None])[..., 0]
        rss = np.sum(ey * ey, axis=1) - np.einsum("sq,sq->s", Xty, beta)
        _, logdet = np.linalg.slogdet(XtX)
        total += float(np.sum(rss) + np.sum(logdet)) + s * w.log_det(n)
    return total


PROPOSAL_WIDTH = 2.0  # the proposal's covariance: this many times the Hessian's
PROPOSAL_DF = 4  # its Student-t degrees of freedom (heavy tails: the likelihood's are lopsided)
DEVIANCE_CHUNK = 250  # proposals a worker takes at a time (Likelihood.deviances)


@dataclass(frozen=True, eq=False)
class Likelihood:
    """One family's REML deviance over a recorder's quiet stretches, and its best value:
    what :meth:`NoiseFit.draw` samples from."""

    family: str
    dt: float
    batches: tuple = field(repr=False)
    bounds: tuple[tuple[float, float], ...]
    best: float

    def deviance(self, theta: np.ndarray) -> float:
        lo, hi = np.array(self.bounds).T
        if np.any(theta < lo) or np.any(theta > hi):
            return math.inf
        try:
            return _deviance(RecorderNoise.from_log_parameters(self.family, theta, self.dt), self.batches)
        except (ValueError, np.linalg.LinAlgError):
            return math.inf

    def deviances(self, thetas: np.ndarray, mapper: Mapper | None = None) -> np.ndarray:
        """The deviance at each row of ``thetas``, over ``mapper``'s workers where it is
        given: a thousand of them took about 0.7 s of a staged-test diagnosis in this
        process, with its workers idle. Each value is computed alone, so the same
        wherever it is computed (the engines pin their workers' threads, as every run
        pins its own)."""
        if mapper is None or len(thetas) < 2:
            return _deviances((self, thetas), np.arange(len(thetas)))
        chunks = [np.arange(a, min(a + DEVIANCE_CHUNK, len(thetas))) for a in range(0, len(thetas), DEVIANCE_CHUNK)]
        return np.concatenate(mapper.map(_deviances, (self, thetas), chunks))

    def draw(self, theta: np.ndarray, cov: np.ndarray, rng: np.random.Generator, size: int,
             mapper: Mapper | None = None) -> list[RecorderNoise]:
        """``size`` models by sampling-importance-resampling (``size`` Student-t proposals
        of scale PROPOSAL_WIDTH x ``cov`` around ``theta``, weighted by the likelihood;
        their deviances computed over ``mapper``, :meth:`deviances`)."""
        d = theta.size
        scale = PROPOSAL_WIDTH * cov
        z = rng.multivariate_normal(np.zeros(d), scale, size=size, method="eigh")
        g = rng.chisquare(PROPOSAL_DF, size) / PROPOSAL_DF
        x = theta + z / np.sqrt(g)[:, None]
        vals, vecs = np.linalg.eigh(scale)
        inv = vecs @ np.diag(1.0 / np.clip(vals, 1e-12, None)) @ vecs.T
        maha = np.einsum("ni,ij,nj->n", x - theta, inv, x - theta)
        log_q = -0.5 * (PROPOSAL_DF + d) * np.log1p(maha / PROPOSAL_DF)
        log_p = -0.5 * (self.deviances(x, mapper) - self.best)
        log_w = np.where(np.isfinite(log_p), log_p - log_q, -np.inf)
        if not np.any(np.isfinite(log_w)):
            x, log_w = theta[None], np.zeros(1)
        w = np.exp(log_w - np.max(log_w))
        pick = rng.choice(len(x), size=size, p=w / w.sum())
        return [RecorderNoise.from_log_parameters(self.family, x[k], self.dt) for k in pick]


def _deviances(payload, chunk) -> np.ndarray:
    """Worker: the deviances of the proposals ``chunk`` indexes (:meth:`Likelihood.deviances`)."""
    likelihood, thetas = payload
    return np.array([likelihood.deviance(thetas[k]) for k in chunk], dtype=float)


def _batches(stretches: Sequence[QuietStretch]):
    groups: dict[tuple[int, int], list[QuietStretch]] = defaultdict(list)
    for s in stretches:
        groups[(s.values.size, s.trend_order)].append(s)
    return [(np.array([s.values for s in g]), np.array([s.regressors() for s in g])) for g in groups.values()]


def pooled_acf(stretches: Sequence[QuietStretch], lags: int = LAGS) -> np.ndarray:
    num, den = np.zeros(lags), 0.0
    for s in stretches:
        r = s.detrended()
        den += float(r @ r)
        for k in range(1, lags + 1):
            if r.size > k:
                num[k - 1] += float(r[k:] @ r[:-k])
    return num / den if den else num


def model_acf(model: RecorderNoise, stretches: Sequence[QuietStretch], lags: int = LAGS) -> np.ndarray:
    """The autocorrelation :func:`pooled_acf` would show on these stretches under
    ``model``: the detrending included (expectations of the same quadratic forms)."""
    num, den = np.zeros(lags), 0.0
    for s in stretches:
        n = s.values.size
        lag = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
        cov = model.sigma ** 2 * model.autocorrelation(lag)
        X = s.regressors()
        P = np.eye(n) - X @ np.linalg.pinv(X)
        C = P @ cov @ P
        den += float(np.trace(C))
        for k in range(1, lags + 1):
            num[k - 1] += float(np.trace(C, offset=k))
    return num / den if den else num


def _starts(family: str, stretches: Sequence[QuietStretch], dt: float) -> list[np.ndarray]:
    """Starting log parameters from the pooled autocorrelation."""
    sd = float(np.sqrt(np.mean(np.concatenate([s.detrended() ** 2 for s in stretches]))))
    rho = pooled_acf(stretches, 6)
    k = n_components(family)
    guesses = [(0.5, 10 * dt), (0.15, 1.0)]
    if rho[0] > 0.05 and rho[5] > 0:  # rho_k = share * phi^k for white + AR(1)
        phi = float(np.clip((rho[5] / rho[0]) ** 0.2, 0.3, 0.99))
        guesses.insert(0, (float(np.clip(rho[0] / phi, 0.05, 0.95)), -dt / math.log(phi)))
    else:
        guesses.insert(0, (0.3, 3 * dt))
    out = []
    for share, tau in guesses[:1] if family in ("white", "ar1") else guesses[:2]:
        if family == "white":
            out.append(np.array([math.log(sd)]))
        elif family == "ar1":
            out.append(np.array([math.log(sd), math.log(tau)]))
        elif k == 1:
            out.append(np.log([sd * math.sqrt(1 - share), sd * math.sqrt(share), tau]))
        else:
            out.append(np.log([sd * math.sqrt(1 - share), sd * math.sqrt(share / 2), tau / 3,
                               sd * math.sqrt(share / 2), tau * 3]))
    return out


def _bounds(family: str, sd: float, dt: float, span: float) -> list[tuple[float, float]]:
    s = (math.log(sd * 1e-3), math.log(sd * 10))
    t = (math.log(dt / 4), math.log(max(span, 10 * dt)))
    k = n_components(family)
    return ([s] if family.startswith("white") else []) + [s, t] * k


def _hessian(f, x: np.ndarray, h: float = 1e-3) -> np.ndarray:
    d = x.size
    H = np.empty((d, d))
    f0 = f(x)
    for i in range(d):
        for j in range(i, d):
            ei, ej = np.eye(d)[i] * h, np.eye(d)[j] * h
            if i == j:
                H[i, i] = (f(x + ei) - 2 * f0 + f(x - ei)) / h ** 2
            else:
                H[i, j] = H[j, i] = (f(x + ei + ej) - f(x + ei - ej) - f(x - ei + ej) + f(x - ei - ej)) / (4 * h * h)
    return H


def fit_family(family: str, stretches: Sequence[QuietStretch], dt: float,
               starts: Sequence[np.ndarray] | None = None) -> tuple[RecorderNoise, float, np.ndarray]:
    """(model, REML deviance, covariance of the log parameters) of one family, from
    ``starts`` (log parameters; default: guesses from the autocorrelation).
    :func:`likelihood_of` gives the deviance it minimised."""
    batches = _batches(stretches)
    sd = float(np.sqrt(np.mean(np.concatenate([s.detrended() ** 2 for s in stretches]))))
    span = max(float(np.ptp(s.time)) for s in stretches)
    bounds = _bounds(family, sd, dt, span)

    def dev(theta: np.ndarray) -> float:
        theta = np.clip(theta, [b[0] for b in bounds], [b[1] for b in bounds])
        try:
            return _deviance(RecorderNoise.from_log_parameters(family, theta, dt), batches)
        except (ValueError, np.linalg.LinAlgError):
            return 1e300

    best = None
    for x0 in (starts if starts is not None else _starts(family, stretches, dt)):
        x0 = np.clip(x0, [b[0] for b in bounds], [b[1] for b in bounds])
        res = optimize.minimize(dev, x0, method="L-BFGS-B", jac="3-point", bounds=bounds)
        if best is None or res.fun < best.fun:
            best = res
    # L-BFGS-B on finite differences stops early where the deviance is flat in a
    # correlation time (it left tau at 0.27 s where the profile's minimum was 0.55 s,
    # 3 units of deviance lower): a simplex polish finishes the job. Its gradient is
    # taken by central differences: forward ones of scipy's default step (1e-8) carried
    # the deviance's rounding (1e-9 of a deviance of 4e4) into the gradient at 0.1, and
    # a change in the last bits of the whitening left tau at 1.01 s where 0.84 s was
    # 0.67 lower (the field tests' first recorder).
    polish = optimize.minimize(dev, best.x, method="Nelder-Mead",
                               options={"xatol": 1e-3, "fatol": 1e-3, "maxiter": 200 * best.x.size})
    if polish.fun < best.fun:
        best = polish
    theta = np.clip(best.x, [b[0] for b in bounds], [b[1] for b in bounds])
    H = _hessian(dev, theta)
    try:
        cov = np.linalg.inv(H)
        if not np.all(np.linalg.eigvalsh(0.5 * (cov + cov.T)) > 0):
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        vals, vecs = np.linalg.eigh(0.5 * (H + H.T))
        cov = vecs @ np.diag(1.0 / np.clip(vals, 1e-6, None)) @ vecs.T
    cov = 2.0 * cov  # the deviance is -2 log L
    return RecorderNoise.from_log_parameters(family, theta, dt), float(best.fun), cov


def whiteness_p(model: RecorderNoise, stretches: Sequence[QuietStretch], lags: int = 10) -> float:
    """Ljung-Box p of the stretches whitened by ``model`` (trends profiled out, lag
    products pooled over stretches): small when the model leaves correlation behind."""
    from scipy import stats

    w = model.whitener()
    num, den, n = np.zeros(lags), 0.0, 0
    for s in stretches:
        X = s.regressors()
        z = w.whiten_runs(np.vstack([s.values, X.T]))
        ey, eX = z[0], z[1:].T
        e = ey - eX @ np.linalg.lstsq(eX, ey, rcond=None)[0]
        den += float(e @ e)
        n += e.size
        for k in range(1, lags + 1):
            num[k - 1] += float(e[k:] @ e[:-k]) if e.size > k else 0.0
    rho = num / den
    q = n * np.sum(rho ** 2)  # pooled: every lag product counted once
    return float(stats.chi2.sf(q, lags))


# A richer family is fitted only when the one below it leaves correlation this significant
# in the quiet data (two slow components cost ten times the fit and rarely win: on the
# field tests white + 2 AR(1) lost to white + AR(1) by 16 in BIC on both recorders).
RICHER_IF_P = 0.01


def likelihood_of(family: str, stretches: Sequence[QuietStretch], dt: float, best: float) -> Likelihood:
    """The deviance :func:`fit_family` minimises, within the same bounds."""
    sd = float(np.sqrt(np.mean(np.concatenate([s.detrended() ** 2 for s in stretches]))))
    span = max(float(np.ptp(s.time)) for s in stretches)
    return Likelihood(family, dt, tuple(_batches(stretches)), tuple(_bounds(family, sd, dt, span)), best)


def fit_noise(stretches: Sequence[QuietStretch], families: Sequence[str] = FAMILIES) -> NoiseFit:
    """The best family (lowest BIC) fitted to the stretches of one recorder; white + two
    AR(1) components only if white + AR(1) leaves the quiet data correlated."""
    if not stretches:
        raise ValueError("no quiet stretch to estimate the noise from")
    dt = float(np.median(np.concatenate([np.diff(s.time) for s in stretches])))
    n = sum(s.values.size - s.trend_order - 1 for s in stretches)
    fits, table = {}, {}
    for family in families:
        starts = None
        if family == "white+2ar1" and "white+ar1" in fits:  # nested: split the one slow part in two
            if whiteness_p(fits["white+ar1"][0], stretches) >= RICHER_IF_P:
                continue
            (sw, ((sa, ta),)) = fits["white+ar1"][0].sigma_white, fits["white+ar1"][0].components
            starts = [np.log([sw, sa * 0.7, ta / 3, sa * 0.7, ta * 3]), np.log([sw * 0.9, sa * 0.5, ta, sa * 0.5, ta * 10])]
        model, deviance, cov = fit_family(family, stretches, dt, starts)
        k = model.log_parameters().size
        table[family] = deviance + k * math.log(n)
        fits[family] = (model, deviance, cov)
    best = min(table, key=table.get)
    model, deviance, cov = fits[best]
    richest = max(fits, key=lambda f: fits[f][0].log_parameters().size)
    return NoiseFit(model, cov, tuple(dict.fromkeys(s.test for s in stretches)),
                    sum(s.values.size for s in stretches), len(stretches), deviance, table,
                    pooled_acf(stretches), model_acf(model, stretches),
                    tuple((s.test, s.kind, float(s.time[0]), float(s.time[-1])) for s in stretches),
                    None if richest == best else (fits[richest][0], fits[richest][2]),
                    {f: likelihood_of(f, stretches, dt, fits[f][1]) for f in {best, richest}})


def campaign_noise(experiments: Sequence[Recorded], *, tails: bool = True,
                   families: Sequence[str] = FAMILIES) -> dict[str, NoiseFit]:
    """One noise model per recorder (tests grouped by sample interval), from all of its
    tests' quiet stretches; returned per test name."""
    by_name = {e.name: e for e in experiments}
    out: dict[str, NoiseFit] = {}
    for names in recorder_groups(experiments):
        stretches = quiet_stretches([by_name[n] for n in names], tails=tails)
        if not stretches:
            raise DataError(f"{', '.join(names)}: no quiet stretch (before a step or an event, or settled) "
                            "of at least 20 valid samples to estimate the recorder's noise from; record from "
                            "before the test starts, or hold the end long enough to settle")
        fit = fit_noise(stretches, families)
        for name in names:
            out[name] = fit
    return out


def noise_models(fits: Mapping[str, NoiseFit]) -> dict[str, RecorderNoise]:
    return {name: fit.model for name, fit in fits.items()}


def moment_noise(stretch: QuietStretch) -> RecorderNoise:
    """White + AR(1) by the method of moments (lags 0 to 2 of the detrended stretch),
    AR(1) or white where those do not fit: instant, for a channel whose noise only feeds
    another's (the frequency under a derived ROCOF), where a REML fit per config load
    would cost seconds (its white part runs to the bound on a PMU's smoothed frequency)."""
    x = stretch.detrended()
    r = [float(np.mean(x[k:] * x[:x.size - k])) for k in range(3)]
    dt = stretch.dt
    if r[1] > 0 and 0 < r[2] / r[1] < 1 and r[1] * r[1] / r[2] < r[0]:
        phi = r[2] / r[1]
        slow = r[1] / phi
        return RecorderNoise(math.sqrt(r[0] - slow), ((math.sqrt(slow), -dt / math.log(phi)),), dt)
    if 0 < r[1] < r[0]:
        return RecorderNoise(0.0, ((math.sqrt(r[0]), -dt / math.log(r[1] / r[0])),), dt)
    return RecorderNoise(math.sqrt(r[0]), (), dt)
