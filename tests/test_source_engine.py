"""The two values passed down from the API (issue 43): where the models come from
(``ModelSource``) and where the work runs (``EngineSpec``)."""

import os
import pickle
import signal
import time
from pathlib import Path

import numpy as np

import pytest

import rapid_cosim as rc
from rapid_cosim.calibration import RunOptions
from rapid_cosim.cli.parser import build_parser
from rapid_cosim.compiler import default_fmu_dir, default_package
from rapid_cosim.errors import BuildError, ConfigError, RapidCosimError
from rapid_cosim.fitting.engine import DaskEngine, JoblibEngine, SequentialEngine, Started


def test_a_model_source_is_a_value_of_paths_with_the_defaults_filled_in_when_resolved(tmp_path, monkeypatch):
    monkeypatch.delenv("RAPID_COSIM_PACKAGE", raising=False)
    monkeypatch.delenv("RAPID_COSIM_FMUS", raising=False)
    given = rc.ModelSource(str(tmp_path / "pkg"), str(tmp_path / "fmus"))
    assert given.package == tmp_path / "pkg" and isinstance(given.fmu_dir, Path) and given.compiler == "auto"
    assert given.users_package and not rc.ModelSource().users_package
    shipped = rc.ModelSource().resolved()
    assert shipped.package == default_package().resolve() and shipped.fmu_dir == default_fmu_dir().resolve()
    monkeypatch.setenv("RAPID_COSIM_PACKAGE", str(tmp_path / "pkg"))
    assert rc.ModelSource().users_package and rc.ModelSource().package_path == tmp_path / "pkg"
    assert pickle.loads(pickle.dumps(given)) == given  # it travels to workers as it is
    with pytest.raises(BuildError, match="unknown compiler 'gcc'; choose one of auto, openmodelica, embedded"):
        rc.ModelSource(compiler="gcc")


def test_a_model_source_builds_and_finds_the_fmus_of_its_folder(fmus):
    folder = fmus["StagedTest"].parent
    source = rc.ModelSource(fmu_dir=folder)
    assert source.fmu("iGrGen.TestBenches.StagedTest") == folder / "iGrGen.TestBenches.StagedTest.fmu"
    assert rc.simulate("iGrGen.TestBenches.StagedTest", stop_time=1.0, output_interval=0.5, source=source).time[-1] == pytest.approx(1.0)


@pytest.mark.parametrize("spec, message", [
    (dict(n_jobs=0), "n_jobs must be a positive number of workers or -1"),
    (dict(n_jobs=-3), "n_jobs must be a positive number of workers or -1"),
    (dict(backend="threads"), "unknown joblib backend 'threads'; choose one of loky, multiprocessing"),
    (dict(scheduler="tcp://x:8786"), "a scheduler address needs the dask backend"),
])
def test_a_bad_engine_is_refused_when_it_is_made(spec, message):
    with pytest.raises(RapidCosimError, match=message):
        rc.EngineSpec(**spec)


def test_an_engine_spec_makes_the_engine_each_stage_needs():
    assert isinstance(rc.EngineSpec().make(), SequentialEngine)
    assert isinstance(rc.EngineSpec(2, "sequential").make(), SequentialEngine)
    two = rc.EngineSpec(2)
    assert isinstance(two.make(), JoblibEngine) and two.make().n_jobs == 2 and two.processes
    assert two.single() == rc.EngineSpec() and not two.single().processes
    dask = rc.EngineSpec(4, "dask", "tcp://h:8786")
    assert isinstance(dask.make(), DaskEngine) and not dask.processes
    assert rc.EngineSpec(-1).workers() >= 1
    assert rc.EngineSpec(2, "multiprocessing").single() == rc.EngineSpec(1, "multiprocessing")  # as archived
    assert dask.local() == rc.EngineSpec(4) and rc.EngineSpec(1, "dask").local().make().workers == 1
    import numpy as np

    assert rc.EngineSpec(np.int64(2)).n_jobs == 2 and type(rc.EngineSpec(np.int64(2)).n_jobs) is int
    with pytest.raises(RapidCosimError):
        rc.EngineSpec(True)


def test_an_archived_engine_is_overridden_setting_by_setting():
    archived = rc.EngineSpec(4, "dask", "tcp://h:8786")
    assert archived.overridden() == archived
    assert archived.overridden(n_jobs=2) == rc.EngineSpec(2, "dask", "tcp://h:8786")
    assert archived.overridden(backend="loky") == rc.EngineSpec(4, "loky")  # another backend drops the scheduler
    assert rc.EngineSpec(2).overridden(backend="dask", scheduler="tcp://o:1") == rc.EngineSpec(2, "dask", "tcp://o:1")


def test_an_archive_holds_the_engine_flat_as_it_always_did():
    """Archives written before the engine was one value are read as they are, and new
    ones hold the same keys in the same order."""
    options = RunOptions(method="nm", seed=3, engine=rc.EngineSpec(2, "multiprocessing"))
    flat = options.to_json()
    assert list(flat) == ["method", "seed", "n_jobs", "backend", "penalty", "estimator_options", "runner", "scheduler"]
    assert flat["n_jobs"] == 2 and flat["backend"] == "multiprocessing" and flat["scheduler"] is None
    assert RunOptions.from_json(flat) == options
    old = {"method": "pf:10+nm", "seed": 1, "n_jobs": 1, "backend": "loky", "penalty": 1e6,
           "estimator_options": {}}  # an archive from before the compiled runner and the scheduler
    read = RunOptions.from_json(old)
    assert read.engine == rc.EngineSpec() and read.runner == "python"
    with pytest.warns(UserWarning, match="the archived engine .* is not one this version runs"):
        gone = RunOptions.from_json({**old, "backend": "threading"})  # a backend older versions ran
    assert gone.engine == rc.EngineSpec() and gone.method == "pf:10+nm"


def test_the_cli_builds_one_engine_and_one_source_from_its_options(tmp_path):
    from rapid_cosim.cli.commands import _engine, _source

    parser = build_parser()
    (tmp_path / "package.mo").write_text("package P\nend P;\n")  # a package, as the CLI checks
    args = parser.parse_args(["identify", "unit.toml", "--n-jobs", "2", "--package", str(tmp_path), "--fmus",
                              str(tmp_path / "f"), "--compiler", "embedded"])
    assert _engine(args) == rc.EngineSpec(2) and _source(args) == rc.ModelSource(tmp_path, tmp_path / "f", "embedded")
    fleet = parser.parse_args(["fleet", "fleet.toml", "--workers", "3"])  # the fleet's older spelling
    assert fleet.n_jobs == 3 and parser.parse_args(["fleet", "fleet.toml"]).n_jobs == 2
    with pytest.raises(RapidCosimError, match="a scheduler address needs the dask backend"):
        _engine(parser.parse_args(["estimate", "cfg.toml", "--scheduler", "tcp://h:1"]))


def _chunk_work(payload, chunk):
    """A worker's chunk: what it was given, and the BLAS threads it ran with."""
    from threadpoolctl import threadpool_info

    if payload == "die" and chunk[0] == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    if isinstance(payload, Path):  # say it is running, then sleep
        (payload / str(chunk[0])).touch()
        time.sleep(120)
    threads = max((p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"), default=None)
    return [(int(k), float(np.sum(np.arange(k + 1.0))), threads, os.getpid(), os.nice(0), time.monotonic_ns())
            for k in chunk]


def test_work_started_early_comes_back_in_order_as_mapped_and_pinned():
    chunks = [np.array([k, k + 5]) for k in range(4)]
    assert rc.EngineSpec(1).start(_chunk_work, "go", chunks) is None  # one worker: mapped when asked
    assert rc.EngineSpec(2).start(_chunk_work, "go", chunks[:1]) is None
    started = rc.EngineSpec(2).start(_chunk_work, "go", chunks)
    parts = started.result()  # closes the pool, whatever happens
    assert [[r[:2] for r in p] for p in parts] == [[r[:2] for r in p] for p in SequentialEngine().map(_chunk_work, "go", chunks)]
    assert all(r[2] == 1 for p in parts for r in p)  # numpy's BLAS found, at one thread, as every engine's chunks run
    assert os.getpid() not in {r[3] for p in parts for r in p}
    assert all(r[4] == min(19, os.nice(0) + 5) for p in parts for r in p)  # below the work waited on


def test_workers_started_ahead_are_the_ones_the_maps_then_run_on():
    assert rc.EngineSpec(1).warm() is None
    assert rc.EngineSpec(2, "sequential").warm() is None
    assert rc.EngineSpec(2, "multiprocessing").warm() is None  # not joblib's reusable pool
    chunks = [np.array([k, k + 5]) for k in range(4)]
    thread = rc.EngineSpec(2).warm()
    parts = JoblibEngine(2).map(_chunk_work, "go", chunks)  # while the workers may still be starting
    thread.join(timeout=120)
    assert not thread.is_alive()
    again = JoblibEngine(2).map(_chunk_work, "go", chunks)
    expected = [[r[:2] for r in p] for p in SequentialEngine().map(_chunk_work, "go", chunks)]
    assert [[r[:2] for r in p] for p in parts] == [[r[:2] for r in p] for p in again] == expected
    assert thread.workers and os.getpid() not in thread.workers
    # one pool, started ahead and kept: a map on a pool made otherwise would have started two more processes
    assert len(set(thread.workers) | {r[3] for p in parts + again for r in p}) <= 2


def test_work_started_early_starts_in_the_order_asked_and_comes_back_in_its_own():
    chunks = [np.array([k]) for k in range(5)]
    with pytest.raises(ValueError, match="each of the 5 chunks once"):
        Started(_chunk_work, "go", chunks, 1, first=[3, 1, 0, 2])
    started = Started(_chunk_work, "go", chunks, 1, first=[3, 1, 0, 2, 4])
    parts = started.result()
    assert [p[0][0] for p in parts] == [0, 1, 2, 3, 4]
    assert sorted(range(5), key=lambda k: parts[k][0][5]) == [3, 1, 0, 2, 4]  # one worker: one after another


def test_work_started_early_on_a_pool_that_loses_a_worker_is_given_back_to_the_caller():
    started = Started(_chunk_work, "die", [np.array([0]), np.array([1])], 2)
    with pytest.warns(UserWarning, match="worker process died"):
        assert started.result() is None


def test_closing_work_started_early_stops_its_workers(tmp_path):
    started = Started(_chunk_work, tmp_path, [np.array([0]), np.array([1])], 2)
    try:
        for _ in range(600):  # until both chunks run
            if all((tmp_path / k).exists() for k in "01"):
                break
            time.sleep(0.1)
        processes = list(started._executor._processes.values())
        assert processes and all(p.is_alive() for p in processes)
    finally:
        started.close()
    for p in processes:
        p.join(timeout=20)
    assert not any(p.is_alive() for p in processes)


@pytest.mark.parametrize("command", [["diagnose", "experiments/test1", "--results", "{tmp}/r"],
                                     ["structures", "experiments/test1", "--structures",
                                      "experiments/structures/TGOV1.toml", "--results", "{tmp}/r"],
                                     ["check", "experiments/test1"]])
def test_a_package_named_wrong_is_said_in_one_line_with_its_option(command, tmp_path, repo, capsys):
    """Not a FileNotFoundError from deep in a run (diagnose and structures), nor a check
    that passes without the package (check)."""
    from rapid_cosim.cli import main

    args = [a.replace("{tmp}", str(tmp_path)) if "{tmp}" in a else (str(repo / a) if a.startswith("experiments") else a)
            for a in command]
    assert main([*args, "--package", str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err
    assert "[--package (source.package)]: no Modelica package at" in err and "nope" in err
    assert "Traceback" not in err


def test_the_api_checks_the_source_it_is_given(tmp_path):
    (tmp_path / "lone.mo").write_text("package lone\nend lone;\n")
    assert rc.ModelSource(package=tmp_path / "lone.mo").check().package == tmp_path / "lone.mo"
    with pytest.raises(ConfigError, match="no Modelica package at"):
        rc.check(str(tmp_path / "config.toml"), source=rc.ModelSource(package=tmp_path / "nope"))


def test_a_diagnosis_gives_the_same_numbers_on_one_worker_and_on_two(repo, tmp_path):
    """Its base model fitted here and its candidates in workers, or everything here: the
    same fits, fitness values and verdict bit for bit (a set's score does not depend on
    the batch or the process it is computed in)."""
    import json

    out = {}
    for n in (1, 2):
        d = rc.diagnose([repo / "experiments" / "test1"], workdir=tmp_path / f"n{n}", engine=rc.EngineSpec(n),
                        log=lambda *a, **k: None)
        out[n] = json.loads(json.dumps(d.to_json(), default=str).replace(str(tmp_path / f"n{n}"), "W"))
        out[n].pop("created", None)
    assert out[1] == out[2]
    assert out[1]["verdict"]
