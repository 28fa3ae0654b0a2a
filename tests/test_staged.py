"""The staged-test workflow on short synthetic tests: both chains archived make-like
(reuse, resume), Table 1 equal to the archives, figures written, the joint fit with its
consistency report; and the pieces with known answers (test lists, Hessian stencil)."""

import csv
import hashlib

import numpy as np
import pytest

from rapid_cosim.archive import RunArchive
from rapid_cosim.cli import main
from rapid_cosim.errors import RapidCosimError
from rapid_cosim.estimators.laplace import hessian_from_stencil, hessian_stencil
from rapid_cosim.calibration.staged import (METHODS, archive_path, archived_tests, ar1_inflation,
                                parse_tests, natural_key)
from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment

ESTIMATE = {"gov.R": {"min": 0.02, "max": 0.12, "label": "R"}, "gov.Ts": {"min": 0.1, "max": 20.0, "label": "Ts"}}
FITNESS = {"offset": True, "noise": "pre-step", "pre_step_end": 5.0}


def _synthetic(fmu, folder, name, df, seed):
    fixed = {"gov.p_ref": 0.6, "src.df": df, "src.t_step": 5.0}
    t, y = synthesize(fmu, {**fixed, "gov.R": 0.055, "gov.Ts": 3.0}, duration=30.0,
                      noise=NoiseModel(white_sigma=0.0006, ar1_sigma=0.0006, phi=0.5, offset=0.001),
                      rng=np.random.default_rng(seed))
    return write_experiment(folder / name, name=name, model="iGrGen.TestBenches.StagedTest", time=t, values=y,
                            fixed=fixed, estimate=ESTIMATE, fitness=FITNESS).parent


@pytest.fixture(scope="module")
def experiments(fmus, tmp_path_factory):
    root = tmp_path_factory.mktemp("staged")
    return root, [_synthetic(fmus["StagedTest"], root / "experiments", "synA", -0.2, 3),
                  _synthetic(fmus["StagedTest"], root / "experiments", "synB", 0.2, 4)]


@pytest.fixture(scope="module")
def results(experiments, fmus, repo):
    root, folders = experiments
    res = root / "results"
    args = ["staged-test", *map(str, folders), "--results", str(res), "--n-jobs", "1", "--quiet",
            "--fmus", str(repo / "fmus"), "--package", str(repo / "modelica" / "iGrGen")]
    assert main(args) == 0
    return res, args


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_staged_test_archives_both_chains_and_draws_the_figure(results):
    res, _ = results
    for test in ("synA", "synB"):
        for m in METHODS:
            with RunArchive(archive_path(res, test, m.key)) as view:
                assert view.status == "finished" and view.method == m.chain and view.seed == 1
                assert view.options["estimator_options"] == m.options
                r = view.result()
            # a synthetic test with known truth: both chains land near it
            assert r.x[0] == pytest.approx(0.055, rel=0.1)
        assert (res / test / f"{test}.png").stat().st_size > 10_000


def test_a_second_invocation_reuses_the_archives(results, capsys):
    res, args = results
    before = {p: _sha(p) for p in res.glob("*/*.h5")}
    assert main(args) == 0
    out = capsys.readouterr().out
    assert out.count("pso10+nm archived, pf10+nm archived") == 2
    assert {p: _sha(p) for p in res.glob("*/*.h5")} == before


def test_an_interrupted_run_is_resumed_to_the_uninterrupted_result(experiments, results, repo, tmp_path,
                                                                  monkeypatch, capsys):
    _, folders = experiments
    res, _ = results
    from rapid_cosim.fitting.objective import ProblemObjective

    calls = {"n": 0}
    real = ProblemObjective.__call__

    def dying(self, X):
        calls["n"] += 1
        if calls["n"] > 4:
            raise KeyboardInterrupt
        return real(self, X)

    monkeypatch.setattr(ProblemObjective, "__call__", dying)
    args = ["staged-test", str(folders[0]), "--results", str(tmp_path), "--n-jobs", "1", "--quiet",
            "--fmus", str(repo / "fmus"), "--package", str(repo / "modelica" / "iGrGen")]
    assert main(args) == 130
    with RunArchive(archive_path(tmp_path, "synA", "pso10+nm")) as view:
        assert view.status == "interrupted" and 0 < view.n_iterations
    monkeypatch.setattr(ProblemObjective, "__call__", real)
    capsys.readouterr()
    assert main(args) == 0
    assert "pso10+nm resumed, pf10+nm new" in capsys.readouterr().out
    for m in METHODS:
        with RunArchive(archive_path(tmp_path, "synA", m.key)) as a, RunArchive(archive_path(res, "synA", m.key)) as b:
            ra, rb = a.result(), b.result()
            assert np.array_equal(ra.x, rb.x) and ra.fun == rb.fun and ra.nfev == rb.nfev


def test_table1_is_what_the_archives_hold(results, capsys):
    res, _ = results
    assert main(["table1", "--results", str(res), "--tests", "synA,synB"]) == 0
    printed = capsys.readouterr().out
    rows = list(csv.DictReader((res / "table1.csv").open()))
    assert [(r["test"], r["method"]) for r in rows] == [(t, m.label) for t in ("synA", "synB") for m in METHODS]
    for row in rows:
        key = next(m.key for m in METHODS if m.label == row["method"])
        with RunArchive(archive_path(res, row["test"], key)) as view:
            r = view.result()
        assert float(row["R"]) == r.x[0] and float(row["Ts"]) == r.x[1]  # CSV keeps full precision
        assert float(row["fitness"]) == r.fun and int(row["nfev"]) == r.nfev
        assert float(row["wall_time"]) == r.wall_time
        assert f"{r.fun:.4e}" in printed and f"{r.x[0]:.4f}" in printed
    md = (res / "table1.md").read_text()
    assert md.count("\n") == 2 + len(rows) and "| synA | PSO10+NM |" in md and "|  | PF10+NM |" in md


def test_table1_names_a_missing_archive(results, capsys):
    res, _ = results
    assert main(["table1", "--results", str(res), "--tests", "synA,synC"]) == 2
    assert "synC" in capsys.readouterr().err


def test_figures_are_written_from_the_archives(results, capsys):
    res, _ = results
    assert main(["figures", "--results", str(res)]) == 0
    out = capsys.readouterr().out
    for f in ("synA/synA.png", "synA/synA-particles.png", "synB/synB-particles.png", "figures/convergence.png"):
        assert (res / f).stat().st_size > 10_000 and str(res / f) in out
    assert not (res / "figures" / "figs3-8.png").exists()  # no test 1-6 among them


def test_joint_fit_and_consistency_report(experiments, results, repo, capsys):
    root, folders = experiments
    res, _ = results
    args = ["joint", "--tests", "synA,synB", "--experiments", str(root / "experiments"), "--results", str(res),
            "--n-jobs", "1", "--quiet", "--option", "smc.n_particles=24", "--option", "smc.n_mcmc_steps=1",
            "--fmus", str(repo / "fmus"), "--package", str(repo / "modelica" / "iGrGen")]
    assert main(args) == 0
    import json

    j = json.loads((res / "joint" / "joint.json").read_text())
    with RunArchive(res / "joint" / "smc.h5") as view:
        post = view.uncertainty()
        assert view.options["estimator_options"] == {"smc": {"n_particles": 24, "n_mcmc_steps": 1}}
    assert j["mean"] == post.mean.tolist() and j["tests"] == ["synA", "synB"]
    for t in j["per_test"]:
        assert -1 <= t["phi"] <= 1 and t["inflation"] == pytest.approx(ar1_inflation(t["phi"]))
        assert np.all(np.linalg.eigvalsh(np.array(t["cov"])) > 0)  # a minimum: positive definite
        assert t["offset_at_joint"] == pytest.approx(0.001, abs=0.001)
    assert j["homogeneity"]["vs_weighted_mean"]["dof"] == 2
    assert (res / "joint" / "joint.png").stat().st_size > 10_000
    md = (res / "joint" / "joint.md").read_text()
    assert "Homogeneity" in md and "synB" in md
    # the Laplace cache is reused: nothing simulated for it the second time
    capsys.readouterr()
    assert main(args) == 0
    assert "Laplace at the optimum" not in capsys.readouterr().out


def test_parse_tests():
    assert parse_tests("1-3,9") == ["test1", "test2", "test3", "test9"]
    assert parse_tests("test2, 2, synA") == ["test2", "synA"]
    assert sorted(["test10", "test2", "test1"], key=natural_key) == ["test1", "test2", "test10"]
    with pytest.raises(RapidCosimError):
        parse_tests("3-1")


def test_hessian_stencil_is_exact_on_a_quadratic():
    A = np.array([[4.0, -1.5], [-1.5, 0.7]])
    x0, h = np.array([0.05, 3.0]), np.array([1e-3, 0.2])
    pts = hessian_stencil(x0, h)
    f = np.array([0.5 * (p - 1) @ A @ (p - 1) + 3 * p[0] for p in pts])
    assert np.allclose(hessian_from_stencil(f, h), A, rtol=1e-6)


def test_ar1_inflation():
    assert ar1_inflation(0.0) == 1.0 and ar1_inflation(-0.2) == 1.0
    assert ar1_inflation(0.5) == pytest.approx(3.0)


def test_archived_tests_skip_the_joint_fit_and_a_diagnosis(tmp_path):
    for f in ("test10/pf10+nm.h5", "test2/pso10+nm.h5", "joint/smc.h5", "diagnose/diagnosis.h5",
              "diagnose/recalibrated.h5"):
        (tmp_path / f).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / f).touch()
    assert archived_tests(tmp_path) == ["test2", "test10"]
