"""Archived runs: re-run bit for bit, resume after kill -9, summaries, locking."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from rapid_cosim.archive import RunArchive
from rapid_cosim.calibration import RunOptions, best_run, inputs_from_configs, rerun, resume_run, start_run
from rapid_cosim.archive.format import text_crc
from rapid_cosim.archive.seal import seal
from rapid_cosim.cli import main
from rapid_cosim.errors import ArchiveDamaged, ArchiveLocked

from conftest import synthetic_config


@pytest.fixture(scope="module")
def config(fmus, tmp_path_factory):
    return synthetic_config(fmus["StagedTest"], tmp_path_factory.mktemp("runs") / "synth", seed=7)


def _histories_equal(a, b):
    assert len(a) == len(b)
    for p, q in zip(a, b):
        assert (p.stage, p.index, p.n_sims, p.rng_state) == (q.stage, q.index, q.n_sims, q.rng_state)
        assert np.array_equal(p.x, q.x) and np.array_equal(p.fitness, q.fitness)
        assert np.array_equal(p.weights, q.weights) and np.array_equal(p.best_x, q.best_x)


def test_rerun_from_the_archive_alone_is_bit_identical(config, tmp_path):
    archive = tmp_path / "run.h5"
    result = start_run(inputs_from_configs([config]), RunOptions(method="pso:3+nm", seed=5), archive, progress=False)
    os.rename(config, config.with_suffix(".moved"))  # the config and data files are not needed any more
    try:
        report = rerun(archive, progress=False)
    finally:
        os.rename(config.with_suffix(".moved"), config)
    assert report.identical, report.first_difference
    assert report.iterations_compared == result.nit
    assert np.array_equal(report.result.x, result.x) and report.result.fun == result.fun
    assert report.simulations > 0


def test_rerun_detects_a_run_that_computes_something_else(config, tmp_path, monkeypatch):
    archive = tmp_path / "run.h5"
    start_run(inputs_from_configs([config]), RunOptions(method="pso:2", seed=5), archive, progress=False)
    from rapid_cosim.fitting.objective import ProblemObjective

    real = ProblemObjective.__call__

    def shifted(self, X):  # as another build of the model would: a hair's breadth off
        ev = real(self, X)
        return type(ev)(ev.fitness + 1e-12, ev.rssd + 1e-12, ev.failed)

    monkeypatch.setattr(ProblemObjective, "__call__", shifted)
    report = rerun(archive, progress=False)
    assert not report.identical and "fitness" in report.first_difference


def test_tampered_bytes_are_named_as_damage(config, tmp_path):
    archive = tmp_path / "run.h5"
    start_run(inputs_from_configs([config]), RunOptions(method="pso:2", seed=5), archive, progress=False)
    import h5py

    with h5py.File(archive, "r+") as f:  # one stored fitness changed, the checksum not
        f["evaluations/fitness"][3] += 1e-9
    with pytest.raises(ArchiveDamaged, match=r"damaged iteration 0 \(checksum mismatch\)"):
        rerun(archive, progress=False)


# The Python runner keeps the run slow enough (seconds) to be killed in the middle.
WRITER = """
import sys
from rapid_cosim.calibration import RunOptions, inputs_from_configs, start_run
start_run(inputs_from_configs([sys.argv[1]]), RunOptions(method="pf:30+nm", seed=11, runner="python",
          estimator_options={"pf": {"n_particles": 30}}), sys.argv[2], progress=False)
"""


def test_resume_after_kill_9_gives_the_uninterrupted_result(config, tmp_path, repo):
    full = tmp_path / "full.h5"
    expected = start_run(inputs_from_configs([config]), RunOptions(method="pf:30+nm", seed=11, runner="python",
                         estimator_options={"pf": {"n_particles": 30}}), full, progress=False)
    killed = tmp_path / "killed.h5"
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(config), str(killed)], cwd=repo)
    try:
        deadline = time.time() + 120
        while time.time() < deadline:
            time.sleep(0.01)
            if killed.exists():
                try:
                    with RunArchive(killed) as view:
                        if view.n_iterations >= 4:
                            break
                except Exception:
                    pass
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()
    with RunArchive(killed) as view:
        assert view.status == "running" and 4 <= view.n_iterations < expected.nit
    with pytest.warns(UserWarning, match="stale lock"):  # and, depending on the moment of the kill, a recovery
        resumed = resume_run(killed, progress=False)
    assert np.array_equal(resumed.x, expected.x) and resumed.fun == expected.fun
    assert (resumed.nfev, resumed.nit, resumed.stop_reason) == (expected.nfev, expected.nit, expected.stop_reason)
    with RunArchive(killed) as a, RunArchive(full) as b:
        assert a.status == "finished"
        _histories_equal(a.iterations(), b.iterations())


def test_an_archive_held_by_a_live_run_is_refused(config, tmp_path):
    archive = tmp_path / "held.h5"
    lock = tmp_path / "held.h5.lock"
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        import socket

        # the lock file as a live run in another process leaves it
        lock.write_text(json.dumps({"pid": holder.pid, "host": socket.gethostname(),
                                    "start": _process_start_time(holder.pid)}))
        with pytest.raises(ArchiveLocked, match=str(holder.pid)):
            start_run(inputs_from_configs([config]), RunOptions(method="nm"), archive, progress=False)
    finally:
        holder.kill()
        holder.wait()


def _process_start_time(pid):
    from rapid_cosim.archive.lock import _process_start

    return _process_start(pid)


def test_cli_estimate_show_json(config, tmp_path, capsys):
    archive = tmp_path / "cli.h5"
    assert main(["estimate", str(config), "--method", "pso:2+nm", "--seed", "3", "--archive", str(archive),
                 "--option", "pso.n_particles=8", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "R " in out and "Ts" in out and "best fitness" in out
    assert main(["show", str(archive), "--json", str(tmp_path / "s.json")]) == 0
    summary = json.loads((tmp_path / "s.json").read_text())
    assert set(summary["best"]) == {"gov.R", "gov.Ts"} and summary["status"] == "finished"
    assert summary["best"]["gov.R"] == pytest.approx(0.06, rel=0.05)


def test_cli_reports_bad_method_and_option_without_writing(config, tmp_path, capsys):
    assert main(["estimate", str(config), "--method", "pf:x+nm", "--archive", str(tmp_path / "a.h5")]) == 2
    assert main(["estimate", str(config), "--option", "pf.particles=5", "--archive", str(tmp_path / "a.h5")]) == 2
    err = capsys.readouterr().err
    assert "pf:x+nm" in err and "n_particles" in err
    assert not (tmp_path / "a.h5").exists()


def test_the_archive_records_its_runner_and_a_rerun_uses_it(config, tmp_path):
    results = {}
    for runner in ("python", "compiled"):
        archive = tmp_path / f"{runner}.h5"
        results[runner] = start_run(inputs_from_configs([config]), RunOptions(method="pso:2+nm", seed=2,
                                    runner=runner), archive, progress=False)
        with RunArchive(archive) as a:
            assert a.options["runner"] == runner
        report = rerun(archive, progress=False)
        assert report.identical, report.first_difference
    # the two runners do the same arithmetic on the test benches, so the runs agree
    assert np.array_equal(results["python"].x, results["compiled"].x)


def test_an_archive_from_before_the_runner_option_reruns_with_the_python_loop(config, tmp_path):
    import h5py

    archive = tmp_path / "old.h5"
    start_run(inputs_from_configs([config]), RunOptions(method="pso:2", seed=4, runner="python"), archive,
              progress=False)
    with h5py.File(archive, "r+") as f:  # as archives were written before the runner was recorded
        options = json.loads(f["inputs/options"].asstr()[()])
        del options["runner"]
        del f["inputs/options"]
        f["inputs"].create_dataset("options", data=json.dumps(options), dtype=h5py.string_dtype("utf-8"))
        f["inputs/options"].attrs["crc32"] = text_crc(json.dumps(options))
    seal(str(archive))  # the edit changed the structure: seal it again, as the writer would
    assert RunOptions.from_json(options).runner == "python"
    report = rerun(archive, progress=False)
    assert report.identical, report.first_difference


def test_best_run_keeps_the_better_search_and_archives_each(config, tmp_path):
    inputs = inputs_from_configs([config])
    weak = RunOptions(method="pso:1", seed=5, estimator_options={"pso": {"n_particles": 2}})
    result, archive = best_run(inputs, weak, tmp_path / "fit.h5", ("pso:3+nm+scan+nm",))
    assert archive == tmp_path / "fit.pso3-nm-scan-nm.h5"  # two particles once cannot beat the chain
    assert {p.name for p in tmp_path.glob("*.h5")} == {"fit.h5", "fit.pso3-nm-scan-nm.h5"}
    with RunArchive(tmp_path / "fit.h5") as first:
        assert first.result().fun > result.fun
    again, same = best_run(inputs, weak, tmp_path / "fit.h5", ("pso:3+nm+scan+nm",))  # both archived: reused
    assert same == archive and again.fun == result.fun


def test_a_workflow_remakes_its_own_archive_of_another_run_and_a_user_archive_is_kept(fmus, tmp_path):
    """ensure_run refuses to overwrite an archive of another run (a user's record), but a
    workflow that owns its folder (replace_stale: a diagnosis re-run after the noise model
    or the data changed) makes it again."""
    from rapid_cosim.calibration import ensure_run
    from rapid_cosim.errors import ArchiveError

    config = synthetic_config(fmus["StagedTest"], tmp_path / "synth", seed=11)
    options = RunOptions(method="nm", seed=1, estimator_options={"nm": {"max_iter": 20}})
    archive = tmp_path / "run.h5"
    first, action = ensure_run(inputs_from_configs([config]), options, archive, progress=False)
    assert action == "new"
    config.write_text(config.read_text().replace("max = 20.0", "max = 19.0"))  # another run now
    changed = inputs_from_configs([config])
    with pytest.raises(ArchiveError, match="holds a run with another experiment config"):
        ensure_run(changed, options, archive, progress=False)
    _, action = ensure_run(changed, options, archive, progress=False, replace_stale=True)
    assert action == "remade"
    with RunArchive(archive) as view:
        assert view.configs == {e.name: e.config_text for e in changed.experiments}
    assert ensure_run(changed, options, archive, progress=False, replace_stale=True)[1] == "archived"


def test_estimate_onto_an_existing_archive_names_resume_before_reading_any_recording(tmp_path, capsys, monkeypatch):
    """Issue 56: it said 'reopen it to resume', after loading the data."""
    import rapid_cosim.api as api

    archive = tmp_path / "run.h5"
    archive.write_bytes(b"an earlier run")
    monkeypatch.setattr(api, "as_experiments", lambda *_: pytest.fail("a recording was read"))
    code = main(["estimate", "experiments/test1", "--archive", str(archive)])
    err = capsys.readouterr().err
    assert code != 0 and f"'rapid-cosim resume {archive}' finishes the run it holds" in err, err
