"""The adequacy null: a parametric bootstrap of the variance ratio and Ljung-Box statistic
over the recorder's noise, the tests' own samples, the profiled offset and the fitted
parameters. Correct models must pass at the stated rate; structure must not."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rapid_cosim.diagnose.candidates import ExperimentResiduals
from rapid_cosim.diagnose.adequacy import adequacy, score_test
from rapid_cosim.diagnose.null import NoiseReplicates, ScoredTest, combined_p, holm, ljung_box_q
from rapid_cosim.diagnose.selection import NoiseFloor
from rapid_cosim.fitting.fitness import Whitening
from rapid_cosim.noise import NoiseFit, RecorderNoise

MODEL = RecorderNoise(0.0012, ((0.0008, 0.9),), 0.1)
N_TESTS, N = 4, 600


@pytest.fixture(scope="module")
def campaign():
    rng = np.random.default_rng(0)
    times = [np.arange(N) * 0.1 + rng.uniform(-0.003, 0.003, N) for _ in range(N_TESTS)]
    fit = NoiseFit.known(MODEL)
    tests = [ScoredTest(f"t{k}", t, Whitening(MODEL, t), True, fit) for k, t in enumerate(times)]
    # a linear "model": two smooth sensitivities shared by the tests (a step and a ramp)
    J = {f"t{k}": np.column_stack([(t > 10) * 1.0, np.clip(t - 10, 0, 20) / 20]) for k, t in enumerate(times)}
    return tests, NoiseReplicates(tests, 1000, seed=1), J


def _observed(tests, J, rng, structure=None):
    """Noise (plus ``structure``) on every test, whitened, offset profiled, and the linear
    model's two parameters fitted over all tests by least squares, as a calibration does."""
    e, Jw = {}, {}
    for t in tests:
        y = MODEL.sample(t.times, rng) + (structure(t.times) if structure else 0.0)
        e[t.name] = t.whitening.residual(y[None], True)[0]
        Jw[t.name] = t.whitening.residual(J[t.name].T, True).T
    A = sum(Jw[k].T @ Jw[k] for k in e)
    beta = np.linalg.solve(A, sum(Jw[k].T @ e[k] for k in e))
    out = {}
    for t in tests:
        w = e[t.name] - Jw[t.name] @ beta
        out[t.name] = ExperimentResiduals(t.name, t.times, np.zeros(N), 0.0, 0.0, N, whitened=w)
    return out, Jw


def test_a_correct_model_is_rejected_at_the_stated_rate(campaign):
    tests, null, J = campaign
    floors = {t.name: NoiseFloor(t.noise) for t in tests}
    rng = np.random.default_rng(2)
    rejected, p_tests = 0, []
    for _ in range(200):
        obs, Jw = _observed(tests, J, rng)
        a = adequacy(obs, floors, null, Jw, [t.name for t in tests], alpha=0.05)
        rejected += not a.adequate
        p_tests += [t.p for t in a.tests]
    assert 0.01 <= rejected / 200 <= 0.10  # family-wise 5 %
    assert 0.06 <= np.mean(np.array(p_tests) < 0.1) <= 0.14  # each test's p uniform


def test_ignoring_the_slow_component_calls_a_correct_model_inadequate(campaign):
    """The issue's failure: whitening white + slow noise as if it were white (or AR(1))
    leaves correlation that a whiteness test calls misfit."""
    tests, _, _ = campaign
    rng = np.random.default_rng(3)
    wrong = RecorderNoise(MODEL.sigma, (), 0.1)
    q = [ljung_box_q(wrong.whiten(MODEL.sample(t.times, rng)[None]))[0] for t in tests for _ in range(5)]
    from scipy import stats

    assert np.median(stats.chi2.sf(q, 10)) < 1e-3
    right = [ljung_box_q(MODEL.whiten(MODEL.sample(t.times, rng)[None]))[0] for t in tests for _ in range(5)]
    assert np.median(stats.chi2.sf(right, 10)) > 0.1


def test_structure_the_size_of_the_noise_is_found(campaign):
    """A misfit of one noise level, oscillating over 8 s after the step (slower misfits
    hide in the slow noise: at 20 s periods the noise is five times as strong as white)."""
    tests, null, J = campaign
    floors = {t.name: NoiseFloor(t.noise) for t in tests}
    rng = np.random.default_rng(4)
    bump = lambda t: 1.4 * MODEL.sigma * np.sin(t / 1.3) * (t > 10)  # noqa: E731
    found = 0
    for _ in range(20):
        obs, Jw = _observed(tests, J, rng, bump)
        found += not adequacy(obs, floors, null, Jw, [t.name for t in tests]).adequate
    assert found >= 18


def _unfitted(tests, J, rng, delta=(0.0, 0.0)):
    """Noise plus the linear model moved by ``delta`` from the truth, nothing fitted (a
    record on file played back): whitened residuals and Jacobians per test."""
    e, Jw = {}, {}
    for t in tests:
        y = MODEL.sample(t.times, rng) + J[t.name] @ np.asarray(delta)
        e[t.name] = t.whitening.residual(y[None], True)[0]
        Jw[t.name] = t.whitening.residual(J[t.name].T, True).T
    return e, Jw


def test_the_score_test_rejects_a_right_point_at_the_stated_rate(campaign):
    tests, null, J = campaign
    rng = np.random.default_rng(5)
    p = np.array([score_test(*_unfitted(tests, J, rng), null).p for _ in range(200)])
    assert 0.01 <= np.mean(p < 0.05) <= 0.10
    assert 0.05 <= np.mean(p < 0.2) <= 0.35  # p spread over (0, 1), not piled at either end


def test_the_score_test_finds_a_moved_parameter_the_variance_cannot_see(campaign):
    """A ramp's slope off by 0.7 noise levels at its end (its misfit 0.3 noise levels
    RMS over the test): the residual's variance is within the noise, the score test sees
    where the parameter moves the response, and its Gauss-Newton step points back."""
    tests, null, J = campaign
    floors = {t.name: NoiseFloor(t.noise) for t in tests}
    rng = np.random.default_rng(6)
    delta = (0.0, 0.7 * MODEL.sigma)
    found_score = found_variance = 0
    steps = []
    for _ in range(20):
        e, Jw = _unfitted(tests, J, rng, delta)
        s = score_test(e, Jw, null)
        found_score += s.p < 0.01
        steps.append(s.step[1])
        obs = {t.name: ExperimentResiduals(t.name, t.times, np.zeros(N), 0.0, 0.0, N, whitened=e[t.name])
               for t in tests}
        found_variance += not adequacy(obs, floors, null, None, []).adequate
    assert found_score >= 18 and found_variance <= 10, (found_score, found_variance)
    assert -1.3 * delta[1] < np.median(steps) < -0.7 * delta[1]  # the step goes back to the truth (the model is linear)


def test_holm_and_the_two_statistics_combined():
    adj = holm({"a": 0.01, "b": 0.04, "c": 0.5})
    assert adj == {"a": 0.03, "b": 0.08, "c": 0.5}
    null_q = np.random.default_rng(1).chisquare(10, 1000)
    null_v = np.random.default_rng(0).chisquare(1000, 1000) / 1000
    pv, pq, pm = combined_p(1.2, 10.0, null_v, null_q)
    # far beyond every replicate: the gamma tail gives the chi-square's own tail, not 1/1001
    assert pv == pytest.approx(stats.chi2.sf(1200, 1000), rel=0.5) and pv < 1e-4
    assert 0.3 < pq < 0.6 and pm == pytest.approx(1 - (1 - pv) ** 2)


def test_kept_replicates_are_taken_only_for_the_same_tests(campaign):
    """An identification's two parts share their replicates (KeptReplicates) only where
    the second's tests would draw the same numbers: the same tests, whitenings, noise
    fits, count and seed. Anything else is drawn anew, and what is taken equals what
    would have been drawn."""
    from dataclasses import replace

    from rapid_cosim.diagnose.null import KeptReplicates

    tests, made, _ = campaign
    kept = KeptReplicates()
    first = kept.get(tests[:2], 200, 3)
    assert kept.get(list(tests[:2]), 200, 3) is first and kept.reused == 1
    fresh = NoiseReplicates(tests[:2], 200, seed=3)
    assert all(np.array_equal(fresh.e[t.name], first.e[t.name]) for t in tests[:2])  # taken = drawn
    other_fit = [replace(tests[0], noise=NoiseFit.known(MODEL)), tests[1]]
    for changed in ((tests[:2], 200, 4), (tests[:2], 100, 3), (tests[1:3], 200, 3), (other_fit, 200, 3),
                    ([replace(tests[0], offset=False), tests[1]], 200, 3),
                    ([replace(tests[0], whitening=Whitening(MODEL, tests[0].times)), tests[1]], 200, 3)):
        assert kept.get(*changed) is not first
    assert kept.reused == 1 and len(kept.made) == 7


def test_the_ljung_box_statistic_is_its_definition_row_by_row():
    """Q = n (n + 2) sum_k rho_k^2 / (n - k), rho_k the lag-k autocorrelation about the
    row's mean, written out for each row against the vectorised one."""
    e = np.random.default_rng(11).standard_normal((7, 300)) + np.linspace(0, 1, 300)
    for row, q in zip(e, ljung_box_q(e, lags=10)):
        d = row - row.mean()
        rho = [np.dot(d[k:], d[:-k]) / np.dot(d, d) for k in range(1, 11)]
        assert q == pytest.approx(300 * 302 * sum(r * r / (300 - k) for k, r in enumerate(rho, start=1)), rel=1e-12)
