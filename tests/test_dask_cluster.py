"""A real dask cluster: a scheduler and two workers as separate processes on 127.0.0.1
(TCP, no shared memory), driven through the command line as a user would.

A worker killed mid-run costs its tasks (dask runs them again on the other worker) and
the result is the single-process one bit for bit; a killed scheduler stops the run with
a clear error, and ``resume`` finishes it on local processes with the same result.
"""

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rapid_cosim.archive import RunArchive
from rapid_cosim.calibration import RunOptions, inputs_from_configs, start_run

from conftest import synthetic_config
METHOD, PARTICLES = "pf:10+nm", 40
DASK = str(Path(sys.executable).with_name("dask"))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Cluster:
    """``threads``: the BLAS and OpenMP pools a bare worker starts with (its environment;
    a worker without a nanny keeps what it is given, where a nanny sets one)."""

    def __init__(self, folder: Path, threads: int | None = None):
        env = {**os.environ, **({v: str(threads) for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                                           "MKL_NUM_THREADS")} if threads else {})}
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        log = open(folder / "cluster.log", "w")
        self.scheduler = subprocess.Popen([DASK, "scheduler", "--host", "127.0.0.1", "--port", str(self.port),
                                           "--no-dashboard"], stdout=log, stderr=subprocess.STDOUT)
        self.workers = [subprocess.Popen([DASK, "worker", self.address, "--no-nanny", "--nthreads", "1",
                                          "--no-dashboard", "--local-directory", str(folder / f"w{k}")],
                                         stdout=log, stderr=subprocess.STDOUT, env=env) for k in range(2)]
        self._wait_for_workers(2)

    def _wait_for_workers(self, n: int, timeout: float = 60.0) -> None:
        from distributed import Client

        deadline = time.time() + timeout
        while time.time() < deadline:
            try:
                with Client(self.address, timeout=5) as c:
                    if len(c.scheduler_info()["workers"]) >= n:
                        return
            except OSError:
                pass
            time.sleep(0.5)
        raise RuntimeError(f"the dask cluster at {self.address} did not start {n} workers")

    def close(self) -> None:
        for p in [*self.workers, self.scheduler]:
            if p.poll() is None:
                p.kill()
            p.wait()


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path)
    yield c
    c.close()


@pytest.fixture(scope="module")
def config(fmus, tmp_path_factory):
    return synthetic_config(fmus["StagedTest"], tmp_path_factory.mktemp("dask") / "synth", seed=3)


@pytest.fixture(scope="module")
def expected(config, tmp_path_factory):
    """The single-process result (the Python runner, as on the cluster below, slow enough
    to be interrupted)."""
    return start_run(inputs_from_configs([config]), RunOptions(method=METHOD, seed=2, runner="python",
                     estimator_options={"pf": {"n_particles": PARTICLES}}),
                     tmp_path_factory.mktemp("local") / "local.h5", progress=False)


def _estimate(config, archive, cluster, repo, n_jobs=("--n-jobs", "2")):
    cmd = [sys.executable, "-m", "rapid_cosim.cli", "estimate", str(config), "--method", METHOD, "--seed", "2",
           "--runner", "python", "--option", f"pf.n_particles={PARTICLES}", "--joblib-backend", "dask",
           "--scheduler", cluster.address, *n_jobs, "--archive", str(archive), "--quiet"]
    return subprocess.Popen(cmd, cwd=repo, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait(archive: Path, n: int, proc, timeout: float = 120.0) -> None:
    deadline = time.time() + timeout
    while time.time() < deadline and proc.poll() is None:
        time.sleep(0.1)
        try:
            with RunArchive(archive) as view:
                if view.n_iterations >= n:
                    return
        except Exception:
            pass
    raise AssertionError(f"the run did not reach {n} iterations (exit {proc.poll()})")


def _result(archive):
    with RunArchive(archive) as view:
        return view.result()


def _cpu_seconds(pid: int) -> float:
    import psutil

    t = psutil.Process(pid).cpu_times()
    return t.user + t.system


def test_the_default_n_jobs_puts_the_work_on_the_cluster(config, expected, cluster, tmp_path, repo):
    """Without --n-jobs (1), the batches still go to every worker of the cluster: each
    worker spends seconds computing, not only the client."""
    before = [_cpu_seconds(w.pid) for w in cluster.workers]
    proc = _estimate(config, tmp_path / "cluster.h5", cluster, repo, n_jobs=())
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    used = [_cpu_seconds(w.pid) - b for w, b in zip(cluster.workers, before)]
    assert min(used) > 1.0, used
    result = _result(tmp_path / "cluster.h5")
    assert np.array_equal(result.x, expected.x) and result.fun == expected.fun


def test_a_killed_worker_leaves_the_result_bit_for_bit(config, expected, cluster, tmp_path, repo):
    archive = tmp_path / "cluster.h5"
    proc = _estimate(config, archive, cluster, repo)
    _wait(archive, 3, proc)
    os.kill(cluster.workers[0].pid, signal.SIGKILL)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    result = _result(archive)
    assert np.array_equal(result.x, expected.x) and result.fun == expected.fun and result.nfev == expected.nfev


def test_a_killed_scheduler_stops_the_run_clearly_and_resume_finishes_it_locally(config, expected, cluster,
                                                                                 tmp_path, repo):
    archive = tmp_path / "cluster.h5"
    proc = _estimate(config, archive, cluster, repo)
    _wait(archive, 3, proc)
    cluster.scheduler.kill()
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 2, err
    assert "lost the dask scheduler" in err and "Traceback" not in err
    assert f"'rapid-cosim resume {archive}" in err
    with RunArchive(archive) as view:
        assert view.status == "interrupted" and view.n_iterations >= 3
    resumed = subprocess.run([sys.executable, "-m", "rapid_cosim.cli", "resume", str(archive),
                              "--joblib-backend", "loky", "--n-jobs", "2", "--quiet"],
                             cwd=repo, capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    result = _result(archive)
    assert np.array_equal(result.x, expected.x) and result.fun == expected.fun and result.nfev == expected.nfev
