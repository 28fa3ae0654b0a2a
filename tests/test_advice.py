"""The advice's refit Monte Carlo (:mod:`rapid_cosim.diagnose.advice`) against brute force.

On rivals whose responses are linear in their parameters the linearised refit is exact, so
each draw's criterion must be the minimum a general bounded optimiser finds, and the
probability the advice states must be the share of draws whose lead clears the threshold
when each is refitted by that optimiser.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import minimize

from rapid_cosim.diagnose.advice import _Old, _refit, settling
from rapid_cosim.diagnose.result import AdvisedTest


def _criterion(old_r, old_J, blocks, u0):
    def c(delta):
        total = sum(r.size * np.log(np.mean((r + J @ delta) ** 2)) for r, J in zip(old_r, old_J))
        return total + sum(e.size * np.log(np.mean((e + G @ delta) ** 2)) for e, G in blocks)
    return c


def _old(old_r, old_J, u0, k):
    return _Old(np.array([r.size for r in old_r], float), np.array([r @ r for r in old_r]),
                np.array([J.T @ r for r, J in zip(old_r, old_J)]), np.array([J.T @ J for J in old_J]), u0, k)


def _fitted_old(rng, d, sizes=(300, 200)):
    """Old tests at their optimum: residuals orthogonal to the Jacobians (J'r = 0 overall)."""
    J = [rng.normal(size=(n, d)) for n in sizes]
    r = [rng.normal(size=n) for n in sizes]
    A = np.vstack(J)
    rr = np.concatenate(r)
    rr -= A @ np.linalg.lstsq(A, rr, rcond=None)[0]
    return np.split(rr, np.cumsum(sizes)[:-1]), J


def test_the_linearised_refit_finds_the_criterions_minimum_per_draw():
    rng = np.random.default_rng(3)
    d = 3
    old_r, old_J = _fitted_old(rng, d)
    u0 = np.array([0.4, 0.5, 0.6])
    G = 0.05 * rng.normal(size=(250, d))
    E = rng.normal(size=(6, 250)) + np.linspace(0, 1.5, 250)  # a systematic difference plus noise
    got = _refit(_old(old_r, old_J, u0, 4), [(E, G)])
    for i in range(E.shape[0]):
        c = _criterion(old_r, old_J, [(E[i], G)], u0)
        res = minimize(c, np.zeros(d), method="L-BFGS-B", bounds=list(zip(-u0, 1 - u0)))
        assert got[i] == pytest.approx(min(res.fun, c(np.zeros(d))), abs=1e-3)
        assert got[i] <= c(np.zeros(d)) + 1e-9  # never worse than no step


class _Linear:
    """A rival whose whitened response on any test is ``base + G u`` (white noise, so the
    whitening is the identity)."""

    def __init__(self, label, base, G, old):
        self.label, self._base, self._G, self.old = label, base, G, old
        self.noise = SimpleNamespace(fit=SimpleNamespace(model=SimpleNamespace(whiten=lambda x: np.asarray(x, float))))

    def responses(self, test, sign):
        return sign * self._base, sign * self._G


def test_the_stated_probability_is_the_share_of_brute_force_refits_that_settle():
    rng = np.random.default_rng(5)
    n, d = 200, 2
    t = np.linspace(0, 1, n)
    shape = np.exp(-5 * t) - np.exp(-15 * t)
    G = np.column_stack([0.02 * np.ones(n), 0.05 * np.sin(3 * t)])
    old_r, old_J = _fitted_old(rng, d)
    u0 = np.array([0.5, 0.5])
    a = _Linear("a", 0.9 * shape, G, _old(old_r, old_J, u0, 4))
    b = _Linear("b", 0.0 * shape, G, _old(old_r, old_J, u0, 4))
    test = AdvisedTest((-0.1, 0.1), 25.0, 10.0, 0.6, False)
    draws = 40
    s = settling([[a], [b]], test, np.random.default_rng(11), {}, draws=draws, threshold=3.0)
    # brute force with the same draws (drawn per truth, per recorded test, in that order)
    z_rng = np.random.default_rng(11)
    ones = np.ones(n) / np.sqrt(n)
    proj = lambda x: x - np.multiply.outer(x @ ones, ones)  # noqa: E731
    for truth, other in ((a, b), (b, a)):
        z = [z_rng.standard_normal((draws, n)) for _ in test.signs]
        crit = {}
        for rival in (a, b):
            out = []
            for k in range(draws):
                blocks = [(proj(sign * truth._base - sign * rival._base + z[i][k]), -proj((sign * G).T).T)
                          for i, sign in enumerate(test.signs)]
                c = _criterion(old_r, old_J, blocks, u0)
                res = minimize(c, np.zeros(d), method="L-BFGS-B", bounds=list(zip(-u0, 1 - u0)))
                out.append(min(res.fun, c(np.zeros(d))))
            crit[rival.label] = np.array(out)
        lead = crit[other.label] - crit[truth.label]  # equal k: the penalty cancels
        assert s.probability[truth.label] == pytest.approx(np.mean(lead >= 3.0), abs=1.5 / draws)
    assert 0.0 < s.worst < 1.0  # a case the test does not settle every time: the comparison means something


def test_an_advised_test_is_recorded_from_the_plant_not_from_its_documentation(study, tmp_path):
    """A plant whose reheat constant is truly 12 s where its documentation says 6 s: the
    advised test's recording must be that plant's (the documented value only in its config)."""
    from rapid_cosim.compiler.source import ModelSource
    from rapid_cosim.diagnose.campaigns import CAMPAIGN, Case, write_advised
    from rapid_cosim.diagnose.result import AdvisedTest
    from rapid_cosim.experiment import load_experiment
    from rapid_cosim.experiment.synthetic import NoiseModel
    from rapid_cosim.simulator import get_simulator

    _, package, fmu_dir = study
    source = ModelSource(package, fmu_dir)
    plant = {"gov.R": 0.05, "gov.Ts": 2.0, "gov.p_ref": 0.6}
    case = Case("doc_T5", 1, plant, {"gov.T5": 12.0}, CAMPAIGN, NoiseModel(white_sigma=1e-6), "staged", 0.0)
    test = AdvisedTest((-0.2, 0.2), 25.0, 10.0, 0.7, True)
    paths = write_advised(case, test, tmp_path, source=source)
    assert len(paths) == 2
    exp = load_experiment(paths[0])
    assert exp.fixed["gov.T5"] == 6.0 and exp.fixed["gov.p_ref"] == 0.7 and exp.fixed["src.df"] == -0.2
    t = exp.data.time
    y = exp.data.columns["pm"]
    sim = get_simulator(source.fmu("iGrGen.TestBenches.StagedTest"))

    def rms(t5):
        traj = sim.simulate({**exp.fixed, **plant, "gov.p_ref": 0.7, "gov.T5": t5}, output_times=t, outputs=["pm"])
        return float(np.sqrt(np.mean((traj["pm"] - y) ** 2)))

    assert rms(12.0) < 1e-4 < rms(6.0)
