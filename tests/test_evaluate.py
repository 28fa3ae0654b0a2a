"""Parallel evaluation: equal results for any n_jobs and backend, penalties on failure."""

import numpy as np
import pytest

from rapid_cosim.fitting.engine import EngineSpec
from rapid_cosim.fitting.objective import PENALTY, ProblemObjective, evaluate_in_detail
from rapid_cosim.experiment import load_experiment
from rapid_cosim.fitting.problem import build_problem
from rapid_cosim.simulator import FmuRef
from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment

TRUTH = {"gov.R": 0.055, "gov.Ts": 3.0}
FIXED = {"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 5.0}
ESTIMATE = {"gov.R": {"min": 0.02, "max": 0.12}, "gov.Ts": {"min": 0.1, "max": 20.0}}


@pytest.fixture(scope="module")
def problem(fmus, tmp_path_factory):
    folder = tmp_path_factory.mktemp("exp") / "synthetic"
    t, y = synthesize(fmus["StagedTest"], {**FIXED, **TRUTH}, duration=30.0,
                      noise=NoiseModel(white_sigma=0.001), rng=np.random.default_rng(3))
    exp = load_experiment(write_experiment(folder, model="iGrGen.TestBenches.StagedTest", time=t, values=y,
                                           fixed=FIXED, estimate=ESTIMATE))
    refs = {exp.model: FmuRef.from_path(fmus["StagedTest"])}
    return build_problem([exp]), refs


def _cloud(problem, n=12, seed=0):
    return problem.space.from_unit(np.random.default_rng(seed).uniform(size=(n, problem.space.dim)))


def test_n_jobs_one_and_two_give_equal_results(problem):
    prob, refs = problem
    X = _cloud(prob)
    one = ProblemObjective(prob, refs, engine=EngineSpec(1).make())(X)
    two = ProblemObjective(prob, refs, engine=EngineSpec(2).make())(X)
    assert np.array_equal(one.fitness, two.fitness)
    assert np.array_equal(one.rssd, two.rssd)
    assert not one.failed.any()


def test_dask_backend_gives_equal_results(problem):
    distributed = pytest.importorskip("distributed")
    prob, refs = problem
    X = _cloud(prob, n=6, seed=1)
    local = ProblemObjective(prob, refs, engine=EngineSpec(1).make())(X)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster):
        remote = ProblemObjective(prob, refs, engine=EngineSpec(2, "dask").make())(X)
    assert np.array_equal(local.fitness, remote.fitness)


def test_truth_scores_near_the_noise_variance(problem):
    prob, refs = problem
    ev = ProblemObjective(prob, refs)(np.array([[TRUTH["gov.R"], TRUTH["gov.Ts"]]]))
    assert ev.fitness[0] == pytest.approx(0.001 ** 2, rel=0.2)
    detail = evaluate_in_detail(prob, refs, np.array([TRUTH["gov.R"], TRUTH["gov.Ts"]]))
    assert detail[0].fit.rssd == ev.fitness[0]


def test_failed_simulations_get_the_penalty_and_the_run_goes_on(tmp_path, blowup_fmu):
    fmu = blowup_fmu
    t = np.linspace(0, 2, 21)
    exp = load_experiment(write_experiment(tmp_path / "bad", model="Bad.Blowup", time=t, values=1 / (1 - 0.1 * t),
                                           fixed={}, estimate={"a": {"min": 0.01, "max": 2.0}},
                                           simulation={"output_interval": 0.05, "timeout": 5.0}))
    prob = build_problem([exp])
    obj = ProblemObjective(prob, {"Bad.Blowup": FmuRef.from_path(fmu)})
    ev = obj(np.array([[0.1], [1.5], [0.2], [0.9]]))  # blows up before t = 2 for a > 0.5
    assert ev.failed.tolist() == [False, True, False, True]
    assert ev.fitness[1] == PENALTY and np.isinf(ev.rssd[1]).all()
    assert ev.fitness[0] < 1e-6
    assert obj.failures.count == 2 and "Blowup" in obj.failures.messages[0]


@pytest.fixture(scope="module")
def whitened(repo):
    """Problems as identify scores them, whitened by their recorders' fitted noise: TG
    Type I on two staged tests (jittered stamps: the band product; weighted by their
    samples) and IEEEG1 on an ANDES event (the stationary whitener)."""
    from rapid_cosim.calibration.inputs import inputs_from_experiments
    from rapid_cosim.noise import campaign_noise
    from rapid_cosim.structures.structure import Structure, on_structure

    out = []
    for structure, tests in (("experiments/structures/TGTypeI.toml", ("experiments/test1", "experiments/test2")),
                             ("experiments/electrical/structures/IEEEG1.toml", ("experiments/electrical/tgtypei_on",))):
        exps = [load_experiment(repo / t) for t in tests]
        inputs = inputs_from_experiments(on_structure(Structure.load(repo / structure), exps, campaign_noise(exps)))
        assert all(e.noise_models for e in inputs.experiments)
        out.append((inputs.problem, inputs.fmus))
    return out


def test_a_sets_score_does_not_depend_on_the_rows_beside_it(whitened):
    """Scored alone, in a batch and split over two workers, a set gets the same residual
    rows and fitness bit for bit: BLAS summed a one-row batch in another order (and the
    band product's transposed rows were reduced in another order), so an optimiser's
    path depended on its batches and on the workers."""
    for prob, refs in whitened:
        X = _cloud(prob, n=13, seed=4)
        here = ProblemObjective(prob, refs)
        ev, R = here.residuals(X)
        for k in range(len(X)):
            one, r = here.residuals(X[k:k + 1])
            assert one.fitness[0] == ev.fitness[k] and np.array_equal(r[0], R[k], equal_nan=True)
            assert here(X[k:k + 1]).fitness[0] == ev.fitness[k]
        assert np.array_equal(here(X[3:8]).fitness, ev.fitness[3:8])
        ev2, R2 = ProblemObjective(prob, refs, engine=EngineSpec(2).make()).residuals(X)
        assert np.array_equal(ev2.fitness, ev.fitness) and np.array_equal(R2, R, equal_nan=True)
        assert not ev.failed.all()
