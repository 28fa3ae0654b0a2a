"""Known parameters back from synthetic data of the project's own model.

Noise-free: every method finds R within 0.5 % and Ts within 2 %. With white noise of 1 %
of the step response, the Bayesian fit's 90 % credible interval covers the truth in at
least 8 of 10 seeded runs (records kept short and particles few, to stay quick).
"""

import numpy as np
import pytest

from rapid_cosim.calibration import inputs_from_configs, log_likelihood_for
from rapid_cosim.estimators import PFOptions, PSOOptions, SMCOptions, run_chain
from rapid_cosim.fitting.engine import EngineSpec
from rapid_cosim.fitting.objective import ProblemObjective
from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment

TRUTH = np.array([0.055, 3.0])  # R, Ts
FIXED = {"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 5.0}
ESTIMATE = {"gov.R": {"min": 0.02, "max": 0.12}, "gov.Ts": {"min": 0.1, "max": 20.0}}
PARAMS = {**FIXED, "gov.R": TRUTH[0], "gov.Ts": TRUTH[1]}


@pytest.fixture(scope="module")
def noise_free(fmus, tmp_path_factory):
    t, y = synthesize(fmus["StagedTest"], PARAMS, duration=30.0, rng=np.random.default_rng(0))
    config = write_experiment(tmp_path_factory.mktemp("clean") / "clean", model="iGrGen.TestBenches.StagedTest",
                              time=t, values=y, fixed=FIXED, estimate=ESTIMATE,
                              fitness={"offset": False, "noise": 0.0005})
    inputs = inputs_from_configs([config])
    return inputs, ProblemObjective(inputs.problem, inputs.fmus)


OPTIONS = {"pf": PFOptions(n_particles=30, max_iter=40), "pso": PSOOptions(n_particles=20, max_iter=40),
           "smc": SMCOptions(n_particles=100)}


@pytest.mark.parametrize("method", ["pf", "pso", "nm", "gd", "smc", "pf:10+nm", "pso:10+nm", "pf:10+gd", "pso:10+gd"])
def test_every_method_recovers_r_and_ts_without_noise(noise_free, method):
    inputs, objective = noise_free
    result = run_chain(objective, inputs.problem.space, method, options=OPTIONS, rng=np.random.default_rng(1),
                       log_likelihood=log_likelihood_for(inputs.problem))
    estimate = result.uncertainty.mean if result.uncertainty is not None else result.x
    rel = np.abs(estimate / TRUTH - 1)
    assert rel[0] < 0.005, f"R off by {100 * rel[0]:.3f} %"
    assert rel[1] < 0.02, f"Ts off by {100 * rel[1]:.3f} %"


def test_bayesian_interval_covers_the_truth_at_its_level(fmus, tmp_path):
    sigma = 0.01 * 0.004 / TRUTH[0]  # 1 % of the step response
    hits, widths = 0, []
    for seed in range(10):
        t, y = synthesize(fmus["StagedTest"], PARAMS, duration=20.0, noise=NoiseModel(white_sigma=sigma),
                          rng=np.random.default_rng(100 + seed))
        config = write_experiment(tmp_path / f"noisy{seed}", model="iGrGen.TestBenches.StagedTest", time=t, values=y,
                                  fixed=FIXED, estimate=ESTIMATE,
                                  fitness={"offset": True, "noise": "pre-step", "pre_step_end": 5.0})
        inputs = inputs_from_configs([config])
        result = run_chain(ProblemObjective(inputs.problem, inputs.fmus, engine=EngineSpec(2).make()), inputs.problem.space, "smc",
                           options={"smc": SMCOptions(n_particles=80, n_mcmc_steps=3)},
                           rng=np.random.default_rng(seed), log_likelihood=log_likelihood_for(inputs.problem))
        interval = result.uncertainty.interval
        hits += bool(np.all((interval[:, 0] <= TRUTH) & (TRUTH <= interval[:, 1])))
        widths.append(interval[:, 1] - interval[:, 0])
    assert hits >= 8, f"the 90 % interval covered the truth in {hits} of 10 runs"
    # and the intervals are informative, not trivially wide
    assert np.median(np.array(widths)[:, 0]) < 0.02 * TRUTH[0]
