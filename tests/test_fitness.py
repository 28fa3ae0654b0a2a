"""rapid_cosim.fitting.fitness: RSSD, ARSSD, experiment fitness and the Gaussian likelihood."""

from __future__ import annotations

import numpy as np
import pytest

from rapid_cosim.errors import ConfigError, SimulationError
from rapid_cosim.experiment import load_experiment
from rapid_cosim.fitting.fitness import (arssd, experiment_fitness, fit_outputs, gaussian_log_likelihood,
                                 rssd)


# --------------------------------------------------------------------------- rssd

def test_rssd_by_hand():
    y = np.array([1.0, 2.0, 3.0])
    assert rssd(y, np.ones(3), np.ones(3, bool)) == pytest.approx(5.0 / 3.0)
    assert rssd(y, y, np.ones(3, bool)) == 0.0


def test_masked_samples_are_excluded():
    y = np.array([1.0, np.nan, 3.0, 100.0])
    yhat = np.array([0.0, 0.0, 1.0, 0.0])
    valid = np.array([True, False, True, False])
    assert rssd(y, yhat, valid) == pytest.approx((1.0 + 4.0) / 2)  # M = 2, not 4


def test_offset_profiling_recovers_a_known_offset_exactly():
    rng = np.random.default_rng(0)
    yhat = np.sin(np.linspace(0, 6, 500))
    e = 0.01 * rng.standard_normal(500)
    e -= e.mean()  # so that the offset is recovered to rounding
    y = yhat + 0.03 + e
    fit = fit_outputs(y, yhat, np.ones(500, bool), offset=True)
    assert fit.offset[0] == pytest.approx(0.03, abs=1e-14)
    assert fit.rssd == pytest.approx(np.mean(e ** 2), rel=1e-10)
    np.testing.assert_allclose(fit.residual, e, atol=1e-14)
    # without profiling, the offset counts in full
    assert rssd(y, yhat, np.ones(500, bool)) == pytest.approx(np.mean(e ** 2) + 0.03 ** 2, rel=1e-10)


def test_offset_uses_valid_samples_only():
    y = np.array([1.5, 2.5, 99.0, 3.5])
    yhat = np.array([1.0, 2.0, 0.0, 3.0])
    fit = fit_outputs(y, yhat, np.array([True, True, False, True]), offset=True)
    assert fit.offset[0] == pytest.approx(0.5) and fit.rssd == pytest.approx(0.0, abs=1e-30)
    assert np.isnan(fit.residual[2])


def test_weighted_mean_over_outputs():
    y = np.zeros((4, 2))
    yhat = np.column_stack([np.ones(4), 2 * np.ones(4)])  # per-output RSSD 1 and 4
    valid = np.ones((4, 2), bool)
    fit = fit_outputs(y, yhat, valid, weights=[1.0, 3.0])
    np.testing.assert_allclose(fit.per_output, [1.0, 4.0])
    assert fit.rssd == pytest.approx((1.0 + 3 * 4.0) / 4)
    assert rssd(y, yhat, valid) == pytest.approx(2.5)
    # weight zero ignores an output, even one without valid samples
    valid[:, 1] = False
    assert rssd(y, yhat, valid, weights=[1.0, 0.0]) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="no valid samples"):
        rssd(y, yhat, valid, weights=[1.0, 1.0])


def test_non_finite_simulation_is_a_simulation_error():
    with pytest.raises(SimulationError):
        rssd(np.zeros(3), np.array([0.0, np.nan, 0.0]), np.ones(3, bool))
    # ... but not where the sample is masked
    assert rssd(np.zeros(3), np.array([0.0, np.nan, 0.0]), np.array([True, False, True])) == 0.0


def test_arssd():
    assert arssd([1e-4, 3e-4]) == pytest.approx(2e-4)
    np.testing.assert_allclose(arssd(np.array([[1.0, 3.0], [2.0, np.inf]])), [2.0, np.inf])
    with pytest.raises(ValueError):
        arssd([])


# --------------------------------------------------------------------------- experiment_fitness

CONFIG = """\
[experiment]
model = "Bench"
[data]
file = "rec.csv"
outputs = { pm = "pm" }
[estimate]
"gov.R" = { min = 0.02, max = 0.12 }
[fitness]
window = [1.0, 8.0]
offset = {offset}
"""


def model(t):
    return 0.6 + 0.05 * (1 - np.exp(-np.clip(t - 2.0, 0, None) / 1.5))


@pytest.fixture
def experiment(tmp_path):
    def build(offset: bool):
        t = np.arange(0, 10.01, 0.1) + 0.003 * np.sin(np.arange(101))  # jittered clock
        t[0] = 0.0
        rows = []
        for k, ti in enumerate(t):
            value = model(ti) + 0.002 + (0.001 if k % 2 else -0.001)
            rows.append(f"{ti:.6f},{'' if k in (40, 41) else f'{value:.9f}'}")
        folder = tmp_path / f"exp_{offset}"
        folder.mkdir()
        (folder / "rec.csv").write_text("time,pm\n" + "\n".join(rows) + "\n")
        (folder / "config.toml").write_text(CONFIG.replace("{offset}", str(offset).lower()))
        with pytest.warns(UserWarning, match="2 in 'pm'"):
            return load_experiment(folder)
    return build


def test_experiment_fitness_window_mask_and_offset(experiment):
    exp = experiment(True)
    t_sim = np.linspace(0, 10.2, 1021)
    fit = experiment_fitness(exp, t_sim, {"pm": model(t_sim)})
    k = np.flatnonzero((exp.data.time >= 1.0) & (exp.data.time <= 8.0))
    assert fit.time.size == k.size > 60
    scored = k[(k != 40) & (k != 41)]  # the two masked samples
    assert fit.n_valid == {"pm": scored.size} and fit.n_samples == scored.size == k.size - 2
    assert np.isnan(fit.residuals["pm"]).sum() == 2
    # The data is model + 0.002 +- 0.001 (alternating); interpolation error is ~1e-6.
    wiggle = np.where(scored % 2, 0.001, -0.001)
    assert fit.offsets["pm"] == pytest.approx(0.002 + wiggle.mean(), abs=1e-6)
    assert fit.rssd == pytest.approx(np.mean((wiggle - wiggle.mean()) ** 2), rel=0.01)


def test_experiment_fitness_without_offset(experiment):
    exp = experiment(False)
    t_sim = np.linspace(0, 10.2, 1021)
    fit = experiment_fitness(exp, t_sim, {"pm": model(t_sim)})
    assert fit.offsets == {"pm": 0.0}
    assert fit.rssd == pytest.approx(0.002 ** 2 + 1e-6, rel=0.05)


def test_experiment_fitness_short_simulation_and_missing_output(experiment):
    exp = experiment(True)
    t_sim = np.linspace(0, 5.0, 501)
    with pytest.raises(SimulationError, match="stop early"):
        experiment_fitness(exp, t_sim, {"pm": model(t_sim)})
    t_sim = np.linspace(0, 10.0, 501)
    with pytest.raises(ConfigError, match="no output 'pm'") as e:
        experiment_fitness(exp, t_sim, {"Pm": model(t_sim)})
    assert e.value.key == "data.outputs.pm"


# --------------------------------------------------------------------------- likelihood

def test_gaussian_log_likelihood_by_hand():
    r = np.array([[1e-4, 4e-4], [2e-4, 1e-4]])
    ll = gaussian_log_likelihood(r, n_samples=[100, 50], sigma=[0.01, 0.02])
    expected = [-0.5 * (100 * 1e-4 / 1e-4 + 50 * 4e-4 / 4e-4),
                -0.5 * (100 * 2e-4 / 1e-4 + 50 * 1e-4 / 4e-4)]
    np.testing.assert_allclose(ll, expected)


def test_gaussian_log_likelihood_matches_the_full_density_up_to_a_constant():
    rng = np.random.default_rng(5)
    y = rng.normal(0, 0.01, 200)
    sims = [np.zeros(200), np.full(200, 0.003), np.linspace(0, 0.01, 200)]
    full = [np.sum(-0.5 * ((y - s) / 0.01) ** 2 - np.log(0.01 * np.sqrt(2 * np.pi))) for s in sims]
    r = np.array([[rssd(y, s, np.ones(200, bool))] for s in sims])
    ll = gaussian_log_likelihood(r, [200], [0.01])
    np.testing.assert_allclose(ll - ll[0], np.array(full) - full[0], rtol=1e-10)


def test_gaussian_log_likelihood_failed_runs_and_shapes():
    ll = gaussian_log_likelihood(np.array([[np.inf, 1.0], [np.nan, 1.0]]), [1, 1], [1.0, 1.0])
    assert np.all(ll == -np.inf)
    with pytest.raises(ValueError):
        gaussian_log_likelihood(np.array([1.0, 2.0]), [1, 1], [1.0, 1.0])
    with pytest.raises(ValueError):
        gaussian_log_likelihood(np.ones((3, 2)), [1, 1], [1.0, 0.0])
