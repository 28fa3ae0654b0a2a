"""SMC against a linear-Gaussian model whose posterior is known in closed form.

y = A theta + e, e ~ N(0, sigma^2 I), uniform prior on a box much wider than the
posterior: the posterior is Gaussian N(mu, P) with P = sigma^2 (A'A)^-1, mu the
least-squares solution, and the evidence is known up to the negligible truncation.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from rapid_cosim.estimators import Evaluations, SearchSpace, SMCOptions, smc
from rapid_cosim.estimators.smc import next_temperature, systematic_resample
from rapid_cosim.estimators.uncertainty import weighted_quantile

SPACE = SearchSpace(("R", "Ts"), np.array([0.02, 0.1]), np.array([0.1, 20.0]))
THETA = np.array([0.05, 5.0])
SIGMA = 0.05
M = 30
T = np.linspace(0.0, 1.0, M)
A = np.column_stack([20.0 * np.ones(M), 0.2 * T])  # y = 20 R + 0.2 t Ts: correlated


class LinearGaussian:
    def __init__(self, seed):
        self.y = A @ THETA + SIGMA * np.random.default_rng(seed).standard_normal(M)
        self.cov = SIGMA**2 * np.linalg.inv(A.T @ A)
        self.mean = np.linalg.solve(A.T @ A, A.T @ self.y)
        self.std = np.sqrt(np.diag(self.cov))

    def __call__(self, X):  # fitness = sum of squared residuals (one experiment)
        return Evaluations.from_fitness(((self.y - X @ A.T) ** 2).sum(axis=1))

    @staticmethod
    def log_likelihood(ev):  # without the constant -M/2 log(2 pi sigma^2)
        return -0.5 * ev.rssd[:, 0] / SIGMA**2

    def interval(self, level):
        return self.mean[:, None] + self.std[:, None] * norm.ppf([(1 - level) / 2, (1 + level) / 2])

    def log_evidence(self):
        """log of integral L(theta) / volume, with L unnormalised as in log_likelihood."""
        ll_max = -0.5 * np.sum((self.y - A @ self.mean) ** 2) / SIGMA**2
        log_volume = np.log(np.prod(SPACE.width))
        return ll_max + 0.5 * np.log(np.linalg.det(2 * np.pi * self.cov)) - log_volume


def run(problem, seed, **options):
    return smc(problem, SPACE, options=SMCOptions(**options), rng=np.random.default_rng(seed),
               log_likelihood=problem.log_likelihood)


def test_posterior_matches_the_analytic_one():
    problem = LinearGaussian(seed=0)
    res = run(problem, seed=1, n_particles=2000)
    post = res.uncertainty
    assert "temperature 1" in res.stop_reason
    assert post.names == SPACE.names and post.level == 0.9
    assert post.weights.sum() == pytest.approx(1.0)
    # Monte-Carlo error of the mean ~ std / sqrt(ESS); allow a generous 0.1 std
    np.testing.assert_array_less(np.abs(post.mean - problem.mean), 0.1 * problem.std)
    np.testing.assert_allclose(post.std, problem.std, rtol=0.1)
    assert np.all(np.abs(post.interval - problem.interval(0.9)) < 0.2 * problem.std[:, None])
    exact_corr = problem.cov[0, 1] / np.prod(problem.std)
    assert post.corr[0, 1] == pytest.approx(exact_corr, abs=0.05)
    np.testing.assert_array_equal(np.diag(post.corr), 1.0)
    assert post.log_evidence == pytest.approx(problem.log_evidence(), abs=0.3)


def test_interval_level_is_honoured():
    problem = LinearGaussian(seed=0)
    post = run(problem, seed=2, n_particles=1500, level=0.5).uncertainty
    assert np.all(np.abs(post.interval - problem.interval(0.5)) < 0.15 * problem.std[:, None])


def test_90_percent_intervals_cover_the_truth_about_90_percent_of_the_time():
    # flat prior, Gaussian likelihood: the credible interval is also a 90 % confidence
    # interval, so over 10 data sets x 2 parameters about 18 of 20 should hold the truth
    covered, width_ratio = 0, []
    for seed in range(10):
        problem = LinearGaussian(seed=100 + seed)
        post = run(problem, seed=seed, n_particles=600).uncertainty
        covered += int(np.sum((post.interval[:, 0] <= THETA) & (THETA <= post.interval[:, 1])))
        width_ratio.append(np.diff(post.interval).ravel() / np.diff(problem.interval(0.9)).ravel())
    assert 15 <= covered <= 20
    # and the intervals are neither too narrow nor too wide (coverage alone cannot see width)
    np.testing.assert_allclose(np.mean(width_ratio, axis=0), 1.0, atol=0.1)


def test_proposals_outside_the_box_are_not_simulated():
    problem = LinearGaussian(seed=0)
    calls = []

    def objective(X):
        calls.append(len(X))
        assert np.all(SPACE.contains(X))
        return problem(X)

    res = smc(objective, SPACE, options=SMCOptions(n_particles=300), rng=np.random.default_rng(0),
              log_likelihood=problem.log_likelihood)
    moves = res.history[1:]
    assert calls[0] == 300 and calls[1:] == [int(it.extras["inside"].sum()) for it in moves]
    assert sum(calls) == res.nfev
    assert all(np.all(~it.extras["accepted"] | it.extras["inside"]) for it in moves)


def test_max_iter_stops_before_temperature_one_and_says_so():
    res = run(LinearGaussian(seed=0), seed=0, n_particles=200, max_iter=4)
    assert res.nit == 4 and "temperature" in res.stop_reason and "< 1" in res.stop_reason
    assert res.history[-1].extras["temperature"] < 1.0


def test_temperatures_increase_with_the_target_ess():
    res = run(LinearGaussian(seed=0), seed=0, n_particles=500, n_final_steps=2)
    temps = [float(it.extras["temperature"]) for it in res.history]
    assert temps[0] == 0.0 and temps[-1] == 1.0 and temps == sorted(temps)
    assert res.history[-1].extras["stage"] == res.history[-3].extras["stage"]  # final moves


def test_next_temperature_hits_the_ess_target():
    rng = np.random.default_rng(0)
    ll = -0.5 * rng.chisquare(3, size=1000) * 50
    log_w = np.full(1000, -np.log(1000))
    lam = next_temperature(log_w, ll, 0.0, 0.5)
    w = np.exp(lam * (ll - ll.max()))
    assert 0 < lam < 1
    assert (w.sum() ** 2 / (w**2).sum()) / 1000 == pytest.approx(0.5, rel=1e-6)
    # particles with zero likelihood do not block tempering
    ll[:600] = -np.inf
    lam = next_temperature(log_w, ll, 0.0, 0.5)
    w = np.exp(lam * (ll[600:] - ll[600:].max()))
    assert (w.sum() ** 2 / (w**2).sum()) / 400 == pytest.approx(0.5, rel=1e-6)


def test_systematic_resampling_keeps_proportions():
    w = np.array([0.13, 0.0, 0.52, 0.35])
    for seed in range(20):  # each count is floor or ceil of N w, zero weight never drawn
        counts = np.bincount(systematic_resample(w, np.random.default_rng(seed)), minlength=4)
        assert counts.sum() == 4 and counts[1] == 0
        assert np.all((counts >= np.floor(4 * w)) & (counts <= np.ceil(4 * w)))
    idx = systematic_resample(np.repeat(w, 250) / 250, np.random.default_rng(1))
    counts = np.bincount(idx // 250, minlength=4)
    assert counts.tolist() == [130, 0, 520, 350]


def test_weighted_quantile_against_unweighted():
    x = np.random.default_rng(0).normal(size=20001)
    q = weighted_quantile(x, np.ones_like(x), np.array([0.05, 0.5, 0.95]))
    np.testing.assert_array_equal(q, np.quantile(x, [0.05, 0.5, 0.95], method="inverted_cdf"))
    # doubling a sample's weight is the same as repeating it
    xs, ws = np.array([0.0, 1.0, 2.0]), np.array([1.0, 2.0, 1.0])
    np.testing.assert_allclose(weighted_quantile(xs, ws, np.array([0.3, 0.7])),
                               weighted_quantile(np.array([0.0, 1.0, 1.0, 2.0]), np.ones(4),
                                                 np.array([0.3, 0.7])))
