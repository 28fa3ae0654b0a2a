"""Faults a run survives: Ctrl-C and SIGTERM, a full disk, a killed worker process, and
options refused before anything is made. Each ends with the uninterrupted result."""

import errno
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from rapid_cosim.archive import RunArchive
from rapid_cosim.archive import format as archive_format
from rapid_cosim.fitting.engine import EngineSpec
from rapid_cosim.calibration import RunOptions, inputs_from_configs, resume_run, start_run, summary_json
from rapid_cosim.cli import main
from rapid_cosim.errors import ArchiveFull

from conftest import gated_objective, synthetic_config
# The Python runner on a 120 s record with 80 particles keeps a run going for seconds
# (each iteration a few tenths), long enough to be interrupted in the middle: with 24
# particles on 25 s a whole run took 0.3 s, and a signal or a kill could come too late.
N_PARTICLES = 80
OPTIONS = dict(method="pf:10+nm", seed=4, runner="python", estimator_options={"pf": {"n_particles": N_PARTICLES}})
CLI_OPTIONS = ["--method", OPTIONS["method"], "--seed", "4", "--runner", "python", "--option",
               f"pf.n_particles={N_PARTICLES}"]
OPEN_CALLS = 5  # objective calls a gated run makes (PF iterations, each archived) before it holds


def _gated_cli(gate):
    """The command line in a subprocess, held at its sixth objective call while ``gate``
    exists (see conftest.gated_objective): no timing decides what the test sees. Its
    Ctrl-C is a terminal's: a harness started in the background (``make test-faults &``
    from a script) hands its children SIGINT ignored, and Python then installs no
    KeyboardInterrupt at all, so every interrupt test timed out there however sound the
    run's own handling."""
    gate.touch()
    return ("import signal\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n" + gated_objective(gate, OPEN_CALLS)
            + "import sys\nfrom rapid_cosim.cli import main\nsys.exit(main(sys.argv[1:]))\n")


@pytest.fixture(scope="module")
def config(fmus, tmp_path_factory):
    return synthetic_config(fmus["StagedTest"], tmp_path_factory.mktemp("faults") / "synth", seed=7, duration=120.0)


@pytest.fixture(scope="module")
def expected(config, tmp_path_factory):
    return start_run(inputs_from_configs([config]), RunOptions(**OPTIONS),
                     tmp_path_factory.mktemp("full") / "full.h5", progress=False)


def _same(result, expected):
    assert np.array_equal(result.x, expected.x) and result.fun == expected.fun
    assert (result.nfev, result.nit) == (expected.nfev, expected.nit)


def _wait_until_held(gate, proc, timeout=60):
    """Until the run holds at its gate (conftest.gated_objective writes gate.held)."""
    held = gate.with_name(gate.name + ".held")
    deadline = time.time() + timeout
    while time.time() < deadline and proc.poll() is None and not held.exists():
        time.sleep(0.02)
    if not held.exists():
        raise AssertionError(f"the run did not reach its gate ({held})")


def _wait_for_iterations(archive, n, proc, timeout=60):
    deadline = time.time() + timeout
    while time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
        try:
            with RunArchive(archive) as view:
                if view.n_iterations >= n and view.status == "running":
                    return
        except Exception:
            pass
    raise AssertionError(f"{archive} did not reach {n} iterations")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupt_closes_the_archive_and_says_how_to_resume(config, expected, tmp_path, repo, sig):
    archive, gate = tmp_path / "run.h5", tmp_path / "gate"
    cmd = [sys.executable, "-c", _gated_cli(gate), "estimate", str(config), *CLI_OPTIONS, "--archive", str(archive),
           "--quiet"]
    proc = subprocess.Popen(cmd, cwd=repo, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for_iterations(archive, 3, proc)
        _wait_until_held(gate, proc)
        proc.send_signal(sig)  # the run holds at the gate: it cannot have finished, nor be in a simulation
        out, err = proc.communicate(timeout=60)
    finally:
        gate.unlink(missing_ok=True)
    assert proc.returncode == 130, err
    assert "holds" in err and f"'rapid-cosim resume {archive}' continues the run" in err
    assert "Traceback" not in err
    with RunArchive(archive) as view:
        assert view.status == "interrupted" and view.n_iterations >= 3
    assert not archive.with_name("run.h5.lock").exists()
    _same(resume_run(archive, progress=False), expected)


def test_a_full_disk_keeps_the_archive_readable_and_it_resumes_once_there_is_space(config, expected, tmp_path,
                                                                                   monkeypatch):
    archive = tmp_path / "run.h5"
    real = archive_format.put_rows
    calls = {"n": 0}

    def filling(ds, start, values):  # the disk fills up in the third commit (nine writes each)
        calls["n"] += 1
        if calls["n"] > 20:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(ds, start, values)

    monkeypatch.setattr(archive_format, "put_rows", filling)
    options = RunOptions(**OPTIONS)
    with pytest.raises(ArchiveFull, match=r"no space left on its device; the archive keeps its \d+ complete "
                                          r"iterations: free space, then 'rapid-cosim resume"):
        start_run(inputs_from_configs([config]), options, archive, progress=False)
    monkeypatch.setattr(archive_format, "put_rows", real)
    with RunArchive(archive) as view:
        kept = view.n_iterations
        assert kept >= 1 and len(view.iterations()) == kept  # readable up to the last complete iteration
    resumed = resume_run(archive, progress=False)
    full = start_run(inputs_from_configs([config]), options, tmp_path / "full.h5", progress=False)
    _same(resumed, full)


def _busy_loky_workers() -> list[int]:
    """This process's loky workers that are running (state R): busy with a batch. An
    idle worker's death is not a lost batch: joblib replaces its pool unasked."""
    mine = str(os.getpid())
    pids = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/stat") as fh:
                state, ppid = fh.read().rsplit(")", 1)[1].split()[:2]
            with open(f"/proc/{pid}/cmdline", "rb") as fh:
                cmdline = fh.read()
        except OSError:
            continue
        if ppid == mine and state == "R" and b"loky" in cmdline and b"popen_loky" in cmdline:
            pids.append(int(pid))
    return pids


def test_a_killed_worker_costs_a_retry_not_the_run(config, expected, tmp_path):
    archive = tmp_path / "run.h5"
    killed = []

    def killer():
        deadline = time.time() + 60
        while time.time() < deadline:  # the run is past its first iterations
            time.sleep(0.02)
            try:
                with RunArchive(archive) as view:
                    if view.n_iterations >= 2:
                        break
            except Exception:
                continue
        while time.time() < deadline and not killed:  # a worker in the middle of a batch
            for pid in _busy_loky_workers()[:1]:
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
            time.sleep(0.002)

    thread = threading.Thread(target=killer, daemon=True)
    thread.start()
    with pytest.warns(UserWarning, match="a worker process died"):
        result = start_run(inputs_from_configs([config]), RunOptions(**{**OPTIONS, "engine": EngineSpec(n_jobs=2)}), archive,
                           progress=False)
    thread.join()
    assert killed
    _same(result, expected)
    with RunArchive(archive) as view:
        events = [str(e) for it in view.iterations() for e in it.extras.get("engine_events", [])]
    assert events and "ran again on a fresh pool" in events[0]


def test_show_counts_what_a_live_run_has_done(config, tmp_path, repo):
    archive, gate = tmp_path / "live.h5", tmp_path / "gate"
    cmd = [sys.executable, "-c", _gated_cli(gate), "estimate", str(config), *CLI_OPTIONS, "--archive", str(archive),
           "--quiet"]
    proc = subprocess.Popen(cmd, cwd=repo, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_for_iterations(archive, 3, proc)
        summary = summary_json(archive)
        with RunArchive(archive) as view:
            its = view.iterations()
    finally:
        proc.kill()
        proc.wait()
        gate.unlink(missing_ok=True)
    n = summary["n_iterations"]
    # the elite particle is carried, not simulated again: all in the first iteration, one fewer after
    assert summary["nfev"] == its[n - 1].n_sims <= N_PARTICLES + (N_PARTICLES - 1) * (n - 1)
    assert summary["nit"] == n


@pytest.mark.parametrize("argv,message", [
    (["--method", "foo"], "unknown method 'foo'"),
    (["--option", "pf.n_particle=3"], "pf has no option 'n_particle'"),
    (["--runner", "python", "--joblib-backend", "loky", "--scheduler", "tcp://127.0.0.1:1"],
     "a scheduler address needs the dask backend"),
])
def test_a_bad_option_is_refused_before_anything_is_announced_or_made(config, tmp_path, capsys, argv, message):
    archive = tmp_path / "never.h5"
    assert main(["estimate", str(config), "--archive", str(archive), *argv]) == 2
    captured = capsys.readouterr()
    assert message in captured.err and captured.out == ""
    assert not archive.exists() and not list(tmp_path.iterdir())


STOPPED_MID_WORK = """
import time
import numpy as np
from rapid_cosim.fitting.engine import Started

def nap(payload, chunk):
    time.sleep(payload)
    return chunk

if __name__ == "__main__":
    started = Started(nap, 600.0, [np.array([k]) for k in range(6)], workers=2)
    time.sleep(3)  # the workers have taken their first chunks
    started.close()
    print("closed", flush=True)
"""


def test_a_started_pool_closed_mid_work_lets_the_process_end(tmp_path):
    """An identification stopped (an error, Ctrl-C) while its standard records' fits run on
    their own pool: closing the pool ends its work and the process exits. Cancelling the
    futures before loky's shutdown, as close() once did, killed loky's manager thread
    (InvalidStateError) and the process could not exit (found on an identify that had
    failed and ran on for an hour, issue 53). The bound below only tells a hang from an
    exit: the workers' chunks would take ten minutes."""
    script = tmp_path / "stopped.py"
    script.write_text(STOPPED_MID_WORK)
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0 and "closed" in proc.stdout, proc.stderr
    assert "InvalidStateError" not in proc.stderr
