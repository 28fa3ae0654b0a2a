"""The null distribution of the adequacy statistics, computed for each campaign.

What a residual of a *correct* model looks like depends on the test: its length and
gaps, the recorder's noise (white plus slow components, estimated from a few thousand
quiet samples and so uncertain itself), the offset profiled out, and the parameters
fitted to the training tests (which take some of the noise with them) or predicted from
them (held-out tests, which carry the estimate's error). Fixed gates on a variance ratio
cannot know all that; a parametric bootstrap does:

1. draw the noise model of each recorder from its estimate's sampling distribution
   (:meth:`rapid_cosim.noise.NoiseFit.draw`), one per replicate;
2. simulate that noise at each test's own sample times (jitter included), whiten it with
   the *estimated* model and profile the offset out, exactly as the fitness does;
3. take out the part a least-squares fit would absorb: with ``J`` the Jacobian of the
   whitened residual at the optimum, ``beta = (J'J)^-1 J' e`` over the training tests,
   and ``e - J beta`` on every test, held-out ones included (the linearised fit);
4. compute each statistic: the variance ratio ``mean(e^2)`` and the Ljung-Box ``Q``,
   their p-values read from the replicates (the far tail from a gamma fitted to them).

Step 2 is the same for every candidate of a diagnosis and is done once
(:class:`NoiseReplicates`); steps 3 and 4 take a candidate's Jacobian.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np
from scipy import stats

from ..experiment.electrical import rocof_component, with_component
from ..fitting.fitness import whitenings
from ..noise import NoiseFit
from ..noise.filtered import FilteredNoise

if TYPE_CHECKING:
    from ..fitting.engine import EngineSpec
    from ..noise.estimate import Mapper

LAGS = 10
REPLICATES = 1000
TAIL_COUNT = 20  # fewer replicates beyond the observed value than this: the tail is read from a fitted gamma
BLOCK = 250  # replicates simulated at once (memory: BLOCK x samples of the campaign)


@dataclass(frozen=True, eq=False)
class ScoredTest:
    """One test as the fitness scores it: the valid sample times, its whitening (the
    estimated model's, :class:`rapid_cosim.noise.whitening.Whitening`), whether the offset is
    profiled, and its recorder's :class:`~rapid_cosim.noise.NoiseFit`."""

    name: str
    times: np.ndarray
    whitening: object
    offset: bool
    noise: NoiseFit
    extra: tuple = ()  # noise components the residual carries beyond the recorder's (the ROCOF's)


def replicates_for(experiments, noise_fits: Mapping[str, NoiseFit], replicates: int = REPLICATES,
                   seed: int = 0, kept: "KeptReplicates | None" = None,
                   engine: "EngineSpec | None" = None) -> "NoiseReplicates":
    """The noise replicates of whitened experiments (one compared output each), whitened
    as their fitness whitens them. An electrical-power test's residual carries the derived
    ROCOF's noise besides the recorder's (:func:`rapid_cosim.experiment.electrical.rocof_component`):
    its replicates carry it too, or a correct model's residual would look too large (a
    null without it put the variance ratio of correct models at 0.8 where they gave 1).
    ``engine``: where the drawn noise models' likelihoods are computed (the same numbers
    anywhere, :meth:`rapid_cosim.noise.estimate.Likelihood.deviances`)."""
    tests = []
    for exp in experiments:
        (w,) = whitenings(exp).values()
        (_, index, _), = exp.scored.columns
        component = rocof_component(exp)
        tests.append(ScoredTest(exp.name, exp.windowed_data().time[index], w, exp.offset, noise_fits[exp.name],
                                (component,) if component else ()))
    mapper = engine.make() if engine is not None and engine.processes else None  # local workers only
    if kept is not None:
        return kept.get(tests, replicates, seed, mapper)
    return NoiseReplicates(tests, replicates, seed=seed, mapper=mapper)


def with_extra(models: list, extra: tuple) -> list:
    """The recorder's drawn models with the residual's further components: the slow-component
    form joins the recorder's; a filtered one is the whitening's own (Whitening.sample)."""
    for component in slow_components(extra):
        models = [with_component(m, component) for m in models]
    return models


def slow_components(extra: tuple) -> tuple:
    """The further components joined to the recorder's model (a filtered one is the
    whitening's own)."""
    return tuple(c for c in extra if not isinstance(c, FilteredNoise))


def ljung_box_q(e: np.ndarray, lags: int = LAGS) -> np.ndarray:
    """Ljung-Box statistic of each row of ``e`` (rows, n). The lagged products are summed
    row by row without a temporary (einsum): over a thousand replicates a product array
    per lag cost five times as much."""
    e = np.atleast_2d(e)
    n = e.shape[1]
    e0 = e - e.mean(axis=1, keepdims=True)
    den = np.einsum("ij,ij->i", e0, e0)
    q = np.zeros(e.shape[0])
    for k in range(1, min(lags, n - 1) + 1):
        rho = np.einsum("ij,ij->i", e0[:, k:], e0[:, :-k]) / den
        q += rho * rho / (n - k)
    return n * (n + 2) * q


class NoiseReplicates:
    """Whitened, offset-profiled noise replicates of every test (step 2 above), kept in
    single precision: the part of the null every candidate shares."""

    def __init__(self, tests: Sequence[ScoredTest], replicates: int = REPLICATES, seed: int = 0,
                 mapper: "Mapper | None" = None):
        self.tests = list(tests)
        self.replicates, self.seed = int(replicates), seed
        rng = np.random.default_rng([seed, 17])
        recorders: dict[int, list] = {}
        for t in self.tests:  # one draw of each recorder's model per replicate, shared by its tests
            if id(t.noise) not in recorders:
                recorders[id(t.noise)] = t.noise.draw(rng, self.replicates, mapper)
        self.e: dict[str, np.ndarray] = {}
        self._stats: dict[bytes, dict] = {}
        for t in self.tests:
            models = with_extra(recorders[id(t.noise)], t.extra)
            out = np.empty((self.replicates, t.times.size), dtype=np.float32)
            for a in range(0, self.replicates, BLOCK):
                raw = t.whitening.sample(models[a:a + BLOCK], rng)
                out[a:a + BLOCK] = t.whitening.residual(raw, t.offset)
            self.e[t.name] = out

    def made_for(self, tests: Sequence[ScoredTest], replicates: int, seed: int) -> bool:
        """Whether these are the replicates ``tests`` would give, number for number: the same
        tests in the same order, each with the same samples, whitening (the same object: a
        whitening is kept per noise model and samples), offset, recorder's noise fit (the
        same object) and further slow components, and the same count and seed."""
        return (int(replicates) == self.replicates and seed == self.seed and len(tests) == len(self.tests)
                and all(_same_test(a, b) for a, b in zip(tests, self.tests)))

    def statistics(self, jacobians: Mapping[str, np.ndarray] | None, training: Sequence[str],
                   lags: int = LAGS) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per test, the null replicates of (variance ratio, Ljung-Box Q) after a
        linearised fit with ``jacobians`` (per test, (n_i, p), on the whitened scale;
        None: nothing fitted). Kept per Jacobian: a fit judged twice costs once."""
        key = b"".join([*(np.ascontiguousarray(jacobians[k]).tobytes() + k.encode() for k in sorted(jacobians or {})),
                        ",".join(training).encode(), str(lags).encode()])
        if key not in self._stats:
            self._stats[key] = self._statistics(jacobians, training, lags)
        return self._stats[key]

    def _statistics(self, jacobians, training, lags) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        beta = None
        if jacobians:
            p = next(iter(jacobians.values())).shape[1]
            A = np.zeros((p, p))
            for name in training:
                A += jacobians[name].T @ jacobians[name]
            A_inv = np.linalg.pinv(A)
            g = np.zeros((self.replicates, p))
            for name in training:
                g += self.e[name].astype(float) @ jacobians[name]
            beta = g @ A_inv  # (replicates, p)
        out = {}
        for t in self.tests:
            e = self.e[t.name].astype(float)
            if beta is not None and t.name in jacobians:
                e -= beta @ jacobians[t.name].T
            out[t.name] = (np.mean(e * e, axis=1), ljung_box_q(e, lags))
        return out


def _same_test(a: ScoredTest, b: ScoredTest) -> bool:
    return (a.name == b.name and a.whitening is b.whitening and a.offset == b.offset and a.noise is b.noise
            and np.array_equal(a.times, b.times) and slow_components(a.extra) == slow_components(b.extra))


class KeptReplicates:
    """The noise replicates one identification has made, handed to both its parts (the
    explanation and the structure selection, as they share one noise fit): the second
    takes the first's where its tests are the same (:meth:`NoiseReplicates.made_for`),
    instead of drawing and whitening the same thousand replicates again (2.5 s of the
    steam unit's 6.4 s of null, in one process and with its workers idle)."""

    def __init__(self):
        self.made: list[NoiseReplicates] = []
        self.reused = 0

    def get(self, tests: Sequence[ScoredTest], replicates: int, seed: int,
            mapper: "Mapper | None" = None) -> NoiseReplicates:
        for r in self.made:
            if r.made_for(tests, replicates, seed):
                self.reused += 1
                return r
        self.made.append(NoiseReplicates(tests, replicates, seed=seed, mapper=mapper))
        return self.made[-1]


def upper_p(observed: float, null: np.ndarray) -> float:
    """Bootstrap p-value of a statistic whose large values speak against the null. Where
    fewer than :data:`TAIL_COUNT` replicates lie beyond the observation, the count says
    little: the tail is then that of a gamma distribution with the replicates' mean and
    variance (both statistics are sums of squares), so that a campaign of ten tests,
    whose Holm threshold is a thousandth, is not judged on one or two replicates."""
    beyond = int(np.sum(null >= observed))
    if beyond >= TAIL_COUNT:
        return float((1 + beyond) / (null.size + 1))
    mean, var = float(np.mean(null)), float(np.var(null))
    if not (mean > 0 and var > 0):
        return float((1 + beyond) / (null.size + 1))
    return float(stats.gamma.sf(observed, mean * mean / var, scale=var / mean))


def combined_p(v: float, q: float, null_v: np.ndarray, null_q: np.ndarray) -> tuple[float, float, float]:
    """(p of the variance ratio, p of Ljung-Box, p of the smaller of the two). Under the
    null the two are independent (the residual's autocorrelations do not depend on its
    scale, for Gaussian white noise exactly), so the smaller p is worth 1 - (1 - p)^2."""
    pv, pq = upper_p(v, null_v), upper_p(q, null_q)
    return pv, pq, float(1.0 - (1.0 - min(pv, pq)) ** 2)


def holm(p: Mapping[str, float]) -> dict[str, float]:
    """Holm's step-down adjusted p-values: rejecting those under alpha keeps the
    family-wise false alarm over the tests at alpha."""
    order = sorted(p, key=p.get)
    m = len(order)
    out, running = {}, 0.0
    for k, name in enumerate(order):
        running = max(running, min(1.0, (m - k) * p[name]))
        out[name] = running
    return out


def timing_jitter(times: np.ndarray) -> float:
    """Standard deviation (s) of a time stamp's error, were the stamps independently off
    their true instants: the intervals' spread over the square root of two (a drifting
    clock, whose stamps wander far from any regular grid, does not count as jitter)."""
    d = np.diff(np.asarray(times, dtype=float))
    if d.size < 2:
        return 0.0
    d = d[d < 1.5 * np.median(d)]  # a missing sample is not jitter
    return float(np.std(d) / np.sqrt(2))
