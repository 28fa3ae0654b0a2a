"""Statistical suites at full size (``make test-slow``; CI runs it after ``make test``).

Each makes the same claim as its smaller version in ``make test``, on more campaigns or
data sets, so that a rate is measured rather than glimpsed:

* the discrepancy workflow over five seeds of every catalogue effect and of none on
  staged campaigns, and one seed of each on recorded-event campaigns, with realistic
  recorder noise (the CI suite runs two seeds of the staged ones);
* SMC credible intervals on an analytic linear-Gaussian problem over 50 data sets
  (the CI suite runs 10);
* SMC intervals of R and Ts on the staged-test bench over 30 noisy synthetic tests
  (the CI suite runs 10).
"""

import shutil

import joblib
import numpy as np
import pytest
from test_estimators_smc import THETA, LinearGaussian, run
from test_recovery import ESTIMATE, FIXED, PARAMS, TRUTH

from rapid_cosim.calibration import inputs_from_configs, log_likelihood_for
from rapid_cosim.compiler import build_models
from rapid_cosim.diagnose.catalogue import BASE_BENCH, EFFECTS
from rapid_cosim.diagnose.study import HIDDEN, confusion_text, draw_case, run_case
from rapid_cosim.diagnose.workflow import DiagnoseOptions
from rapid_cosim.fitting.engine import EngineSpec
from rapid_cosim.estimators import SMCOptions, run_chain
from rapid_cosim.fitting.objective import ProblemObjective
from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment
from rapid_cosim.compiler.source import ModelSource

pytestmark = pytest.mark.slow


def test_the_workflow_names_the_hidden_effect_over_five_seeds(repo, tmp_path):
    package = tmp_path / "package" / "iGrGen"
    shutil.copytree(repo / "modelica" / "iGrGen", package)
    fmu_dir = tmp_path / "fmus"
    build_models(list(dict.fromkeys([BASE_BENCH, *(e.bench for e in EFFECTS.values())])), package=package, fmu_dir=fmu_dir,
                 log=lambda *_: None)
    cases = [draw_case(t, s, source=ModelSource(package=package, fmu_dir=fmu_dir)) for t in [*HIDDEN, "none"] for s in range(1, 6)]
    cases += [draw_case(t, 1, source=ModelSource(package=package, fmu_dir=fmu_dir), kind="event") for t in [*HIDDEN, "none"]]
    options = DiagnoseOptions(write_model=False, max_effects=1)
    results = joblib.Parallel(n_jobs=2)(joblib.delayed(run_case)(c, tmp_path / "cases", options=options,
                                                                 source=ModelSource(package, fmu_dir)) for c in cases)
    print("\n" + confusion_text(results))
    effects = [r for r in results if r.case.truth != "none"]
    null = [r for r in results if r.case.truth == "none"]
    assert sum(r.correct for r in effects) >= 0.9 * len(effects)
    assert all(r.named_first == "none" and r.diagnosis.adequate for r in null), \
        [(r.case.label, r.diagnosis.named.verdict) for r in null if not (r.named_first == "none" and r.diagnosis.adequate)]
    wrongly_named = [r for r in effects if not r.correct and r.named_first not in ("ambiguous", "none")]
    assert not wrongly_named, [(r.case.label, r.named_first) for r in wrongly_named]
    assert all(r.gap_shrink >= 0.5 for r in effects if r.correct)


def test_smc_intervals_are_the_exact_ones_over_50_data_sets():
    """Coverage of the truth by the SMC intervals, against that of the exact analytic
    intervals on the same data (the data's own luck cancels), and their widths."""
    covered, exact, ratios = 0, 0, []
    for seed in range(50):
        problem = LinearGaussian(seed=1000 + seed)
        post = run(problem, seed=seed, n_particles=600).uncertainty
        truth_inside = lambda iv: int(np.sum((iv[:, 0] <= THETA) & (THETA <= iv[:, 1])))  # noqa: E731
        covered += truth_inside(post.interval)
        exact += truth_inside(problem.interval(0.9))
        ratios.append(np.diff(post.interval).ravel() / np.diff(problem.interval(0.9)).ravel())
    # 100 intervals at 90 %: binomial standard deviation 3 around 90
    assert 80 <= exact <= 100 and abs(covered - exact) <= 3, (covered, exact)
    np.testing.assert_allclose(np.mean(ratios, axis=0), 1.0, atol=0.05)


def test_intervals_of_r_and_ts_cover_the_truth_over_30_synthetic_tests(fmus, tmp_path):
    sigma = 0.01 * 0.004 / TRUTH[0]
    hits = 0
    for seed in range(30):
        t, y = synthesize(fmus["StagedTest"], PARAMS, duration=20.0, noise=NoiseModel(white_sigma=sigma),
                          rng=np.random.default_rng(500 + seed))
        config = write_experiment(tmp_path / f"noisy{seed}", model="iGrGen.TestBenches.StagedTest", time=t,
                                  values=y, fixed=FIXED, estimate=ESTIMATE,
                                  fitness={"offset": True, "noise": "pre-step", "pre_step_end": 5.0})
        inputs = inputs_from_configs([config])
        result = run_chain(ProblemObjective(inputs.problem, inputs.fmus, engine=EngineSpec(2).make()),
                           inputs.problem.space, "smc", options={"smc": SMCOptions(n_particles=80, n_mcmc_steps=3)},
                           rng=np.random.default_rng(seed), log_likelihood=log_likelihood_for(inputs.problem))
        interval = result.uncertainty.interval
        hits += bool(np.all((interval[:, 0] <= TRUTH) & (TRUTH <= interval[:, 1])))
    # two 90 % intervals held together: 0.81 to 0.9 of the runs, binomial sd about 2
    assert hits >= 22, f"both intervals covered the truth in {hits} of 30 runs"
