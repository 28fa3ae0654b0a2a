"""The recorder's noise model: exact whitening, simulation, the REML fit over quiet
stretches, the [noise] config section and the whitened fitness built on it."""

from __future__ import annotations

import numpy as np
import pytest

from rapid_cosim.errors import ConfigError
from rapid_cosim.experiment import experiment_from_arrays
from rapid_cosim.fitting.fitness import batch_residuals, batch_rssd, combination_weights, experiment_fitness
from rapid_cosim.noise import NoiseFit, QuietStretch, RecorderNoise, fit_noise, quiet_windows
from rapid_cosim.noise.estimate import DRAW_FACTOR

FIELD_LIKE = RecorderNoise(0.0012, ((0.0008, 0.9),), 0.1)  # what the field tests' quiet data show


def _dense_whitening(model: RecorderNoise, n: int) -> np.ndarray:
    lag = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    return np.linalg.inv(np.linalg.cholesky(model.sigma ** 2 * model.autocorrelation(lag)))


@pytest.mark.parametrize("model", [FIELD_LIKE, RecorderNoise(0.001, ((0.0005, 0.3), (0.0004, 3.0)), 0.04),
                                   RecorderNoise(0.0, ((0.001, 0.5),), 0.1), RecorderNoise(0.001, (), 0.1)],
                         ids=["white+ar1", "white+2ar1", "ar1", "white"])
@pytest.mark.parametrize("n", [30, 700])
def test_whitening_is_the_inverse_cholesky_factor_of_the_covariance(model, n):
    """The Kalman innovations, standardised, are L^-1 r with Cov = L L': the dense
    transient and the steady-state filter together, for runs shorter and longer than
    the transient."""
    y = np.random.default_rng(1).standard_normal((3, n))
    expected = y @ _dense_whitening(model, n).T
    assert np.allclose(model.whitener().whiten_runs(y), expected, atol=1e-6)


def test_a_gap_breaks_the_chain():
    model = FIELD_LIKE
    r = np.random.default_rng(2).standard_normal(200) * 1e-3
    r[80] = np.nan
    e = model.whiten(r)
    assert np.isnan(e[80])
    w = model.whitener()
    assert np.allclose(e[:80], w.whiten_runs(r[None, :80])[0])
    assert np.allclose(e[81:], w.whiten_runs(r[None, 81:])[0])  # from the stationary prior again


def test_samples_on_jittered_times_have_the_model_autocorrelation():
    rng = np.random.default_rng(3)
    t = np.arange(40000) * 0.1 + rng.uniform(-0.004, 0.004, 40000)
    x = FIELD_LIKE.sample(t, rng)
    x = x - x.mean()
    acf = [np.mean(x[k:] * x[:-k]) / np.var(x) for k in (1, 2, 5, 10)]
    assert np.std(x) == pytest.approx(FIELD_LIKE.sigma, rel=0.03)
    assert np.allclose(acf, FIELD_LIKE.autocorrelation(np.array([1, 2, 5, 10])), atol=0.03)
    e = FIELD_LIKE.whiten(x)
    assert np.var(e) == pytest.approx(1.0, abs=0.03)
    assert abs(np.corrcoef(e[1:], e[:-1])[0, 1]) < 0.02


def _stretches(model, rng, n_stretches=12, n=100, trend=True):
    out = []
    for k in range(n_stretches):
        t = np.arange(n) * model.dt + rng.uniform(-0.003, 0.003, n)
        drift = 0.002 * (t - t.mean()) / 10 if trend else 0.0  # a slow drift the trend absorbs
        out.append(QuietStretch(f"t{k % 4}", "pre-step", t, 0.6 + drift + model.sample(t, rng), 1))
    return out


def test_the_fit_recovers_white_plus_slow_noise_from_short_quiet_windows():
    """Twelve 10 s windows (1200 samples) of white + OU noise with a drift: REML picks
    white + AR(1) by BIC and recovers its parameters within their stated uncertainty."""
    rng = np.random.default_rng(4)
    fit = fit_noise(_stretches(FIELD_LIKE, rng))
    assert fit.family == "white+ar1", fit.families
    theta, se = fit.model.log_parameters(), fit.standard_errors()
    truth = FIELD_LIKE.log_parameters()
    assert np.all(np.abs(theta - truth) < 3 * se + 0.05), (np.exp(theta), np.exp(truth), se)
    assert fit.families["white+ar1"] < fit.families["ar1"] - 10 and fit.families["white+ar1"] < fit.families["white"] - 10
    assert np.allclose(fit.acf[:6], fit.acf_model[:6], atol=0.08)


def test_white_noise_is_fitted_as_white():
    rng = np.random.default_rng(5)
    fit = fit_noise(_stretches(RecorderNoise(0.001, (), 0.1), rng))
    assert fit.family == "white", fit.families
    assert fit.model.sigma == pytest.approx(0.001, rel=0.05)


def test_draws_follow_the_likelihood_of_the_quiet_data():
    """Draws come from the REML likelihood itself: their deviance above the best is
    chi-square with as many degrees of freedom as parameters (mean 3, median 2.37 for white
    + AR(1)); they spread at least as far as the Hessian says, further along the
    lopsided correlation time."""
    rng = np.random.default_rng(6)
    fit = fit_noise(_stretches(FIELD_LIKE, rng))
    likelihood = fit.likelihoods[fit.model.family]
    models = fit.draw(np.random.default_rng(0), 2000)
    excess = np.array([likelihood.deviance(m.log_parameters()) - likelihood.best for m in models])
    assert 2.6 < excess.mean() < 3.5 and 1.9 < np.median(excess) < 2.9
    draws = np.array([m.log_parameters() for m in models])
    assert np.all(np.std(draws, axis=0) > 0.9 * fit.standard_errors())
    assert len({tuple(d) for d in draws}) > 500  # resampled from many proposals, not a few
    assert np.array_equal(NoiseFit.known(FIELD_LIKE).draw(rng, 3)[0].log_parameters(), FIELD_LIKE.log_parameters())


def test_noise_models_drawn_on_workers_are_the_ones_drawn_here():
    """The null's proposals' likelihoods may be computed on an engine's workers: the same
    deviances bit for bit, in the same order, so the same models drawn."""
    import rapid_cosim as rc
    from rapid_cosim.fitting.engine import pinned_threads

    fit = fit_noise(_stretches(FIELD_LIKE, np.random.default_rng(6)))
    likelihood = fit.likelihoods[fit.model.family]
    workers = rc.EngineSpec(2).make()
    with pinned_threads():  # as every run is, here and in the workers
        here = fit.draw(np.random.default_rng(0), 300)
        there = fit.draw(np.random.default_rng(0), 300, workers)
        thetas = np.array([m.log_parameters() for m in here[:6]] + [np.full(here[0].log_parameters().size, 50.0)])
        serial = np.array([likelihood.deviance(t) for t in thetas])
    assert [m.log_parameters().tobytes() for m in here] == [m.log_parameters().tobytes() for m in there]
    assert np.array_equal(likelihood.deviances(thetas, workers), serial) and np.isinf(serial[-1])
    assert np.array_equal(likelihood.deviances(thetas), serial)


def test_an_undetermined_component_draws_bounded_models():
    """A covariance the quiet data cannot pin down (huge, or not finite) still draws
    recorders: each parameter within the truncation factor of the estimate."""
    fit = fit_noise(_stretches(FIELD_LIKE, np.random.default_rng(6)))
    theta = fit.model.log_parameters()
    for cov in (np.diag(np.full(theta.size, 400.0)), np.full((theta.size, theta.size), np.nan)):
        wide = NoiseFit(fit.model, cov, fit.tests, fit.n_samples, fit.n_stretches, fit.deviance, fit.families,
                        fit.acf, fit.acf_model)
        draws = np.array([m.log_parameters() for m in wide.draw(np.random.default_rng(1), 500)])
        assert np.all(np.abs(draws - theta) <= np.log(DRAW_FACTOR) + 1e-12)
        assert np.ptp(draws, axis=0).min() > 0.5 * np.log(DRAW_FACTOR)


def _staged(noise: dict | None = None, t_return=60.0, n=1101):
    t = np.arange(n) * 0.1
    pm = 0.6 + 0.08 * (t >= 10) * (t < t_return) + 0.001 * np.random.default_rng(7).standard_normal(n)
    fixed = {"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 10.0, "src.t_return": t_return}
    exp = experiment_from_arrays("s", "iGrGen.TestBenches.StagedTest", t, {"pm": pm}, fixed=fixed,
                                 estimate={"gov.R": (0.02, 0.12)}, fitness={"offset": True, "pre_step_end": 10.0})
    if noise is None:
        return exp
    from rapid_cosim.experiment import parse_experiment, render_config
    import tomllib

    raw = tomllib.loads(exp.config_text)
    raw["noise"] = noise
    return parse_experiment(render_config(raw), exp.config_path, data=exp.data)


def test_quiet_windows_are_the_pre_step_and_settled_chunks():
    windows = quiet_windows(_staged())
    assert windows[0] == ("pre-step", 0.0, 10.0, 1)
    settled = [(a, b) for kind, a, b, _ in windows if kind == "settled"]
    assert settled == [(40.0, 60.0), (90.0, pytest.approx(110.0, abs=1e-6))]


def test_a_noise_section_makes_the_fitness_whitened_least_squares():
    exp = _staged({"pm": FIELD_LIKE.to_config()})
    assert exp.noise_models["pm"] == FIELD_LIKE
    scored = exp.scored.measured[:, 0]
    rng = np.random.default_rng(8)
    sims = (scored - 0.001 + 1e-3 * rng.standard_normal((4, scored.size)))[:, :, None]  # offset 0.001
    values = batch_rssd(exp, sims)
    R = batch_residuals(exp, sims)
    assert np.allclose(np.sum(R ** 2, axis=1), values)  # squares sum to the value
    assert np.all((values > 0.5) & (values < 2.0))  # about one for noise at the model's level... of 1e-3
    fit = experiment_fitness(exp, exp.windowed_data().time, {"pm": sims[0, :, 0]})
    assert fit.rssd == pytest.approx(values[0])
    assert fit.offsets["pm"] == pytest.approx(0.001, abs=5e-4)  # the GLS offset
    assert np.sum(np.isfinite(fit.whitened["pm"])) == scored.size
    assert combination_weights([exp, exp]).tolist() == [scored.size, scored.size]
    with pytest.raises(ConfigError, match="every experiment the same way"):
        combination_weights([exp, _staged()])


@pytest.mark.parametrize("noise, key, message", [
    ({"pm": {"white": 0.001, "dt": 0.04}}, "noise.pm.dt", "median sample interval"),
    ({"pm": {"white": -0.001, "dt": 0.1}}, "noise.pm.white", ">= 0"),
    ({"pm": {"dt": 0.1}}, "noise.pm", "white part or a slow component"),
    ({"pm": {"white": 0.001, "dt": 0.1, "components": [{"sigma": 0.001, "tau": 0}]}}, "noise.pm.components[0]",
     "must be positive"),
    ({"p": {"white": 0.001, "dt": 0.1}}, "noise.p", "not an output"),
    ({"pm": {"white": 0.001, "dt": 0.1, "colour": "pink"}}, "noise.pm.colour", "unknown key"),
])
def test_a_bad_noise_section_names_its_key(noise, key, message):
    with pytest.raises(ConfigError, match=message) as e:
        _staged(noise)
    assert e.value.key == key


def test_a_masked_sample_or_two_does_not_cut_a_quiet_stretch_and_a_longer_run_does():
    """A frame flagged invalid is out of the quiet data as a dropped frame is, and the
    stretch runs on across it: cutting there split 10 s of pre-event data into pieces,
    each with its own trend, and tripled the correlation time's error. Three masked
    samples in a row cut (MAX_MASKED_RUN)."""
    from rapid_cosim.noise.quiet import MAX_MASKED_RUN, quiet_stretches

    def pre_step(masked):
        t = np.arange(1101) * 0.1
        pm = 0.6 + 0.08 * (t >= 10) * (t < 60) + 0.001 * np.random.default_rng(7).standard_normal(t.size)
        pm[list(masked)] = np.nan
        exp = experiment_from_arrays("s", "iGrGen.TestBenches.StagedTest", t, {"pm": pm},
                                     fixed={"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 10.0, "src.t_return": 60.0},
                                     estimate={"gov.R": (0.02, 0.12)}, fitness={"offset": True, "pre_step_end": 10.0})
        return [s.time.size for s in quiet_stretches([exp]) if s.kind == "pre-step"]

    assert pre_step([]) == [100]
    assert pre_step([30, 31]) == [98]  # two in a row: one stretch
    assert pre_step([30, 60]) == [98]  # two apart: one stretch
    assert pre_step(range(40, 40 + MAX_MASKED_RUN + 1)) == [40, 57]  # three in a row: cut


def test_a_recording_with_no_quiet_stretch_is_a_data_error_naming_it():
    """Stepped 1 s in (10 samples before it) and never settled: nothing to estimate the
    recorder's noise from. The user's error type, with the test's name, not a ValueError."""
    from rapid_cosim.errors import DataError
    from rapid_cosim.noise import campaign_noise

    t = np.arange(300) * 0.1
    pm = 0.6 + 0.08 * (t >= 1.0) + 0.001 * np.random.default_rng(3).standard_normal(t.size)
    exp = experiment_from_arrays("short", "iGrGen.TestBenches.StagedTest", t, {"pm": pm},
                                 fixed={"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 1.0, "src.t_return": 100.0},
                                 estimate={"gov.R": (0.02, 0.12)}, fitness={"offset": True, "pre_step_end": 1.0})
    with pytest.raises(DataError, match="short: no quiet stretch"):
        campaign_noise([exp])
