"""The HDF5 run archive: exact round trips, locking, reopening, and kill -9 of the writer."""

from __future__ import annotations

import hashlib
import json
import os
import random
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from rapid_cosim.archive import ArchiveWriter, RunArchive, data_sha256
from rapid_cosim.archive import format as store_format
from rapid_cosim.archive import seal
from rapid_cosim.archive import writer as store_writer
from rapid_cosim.errors import ArchiveError, ArchiveLocked
from rapid_cosim.estimators.base import EstimationResult, Iteration
from rapid_cosim.estimators.uncertainty import Uncertainty

D, E = 3, 2
NAMES = ("Kp", "Ti", "droop")
SIZES = (50, 1, 1, 5, 0, 17)  # evaluations per iteration, cycled
SMALL_ROOM = {"evaluations": 60, "table": 3, "rng_state": 700, "extras": 900}


def make_iteration(i: int) -> tuple[Iteration, np.ndarray]:
    """Iteration ``i`` of a synthetic run: a pure function of ``i``, awkward values included."""
    g = np.random.default_rng(i)
    n = SIZES[i % len(SIZES)]
    x = g.random((n, D))
    fitness = g.random(n)
    rssd = g.random((n, E))
    if n:
        x[0, 0] = -0.0
        fitness[-1] = [np.inf, np.nan, 1e-310][i % 3]  # a failure penalty, a NaN, a subnormal
        rssd[0, -1] = np.frombuffer(b"\x01\0\0\0\0\0\xf8\x7f", "<f8")[0]  # NaN with a payload
    extras = [
        {},
        {"velocity": g.standard_normal((n, D))},
        {"temperature": np.float64(g.random()), "accepted": g.random(n) > 0.5},
        {"simplex": g.random((D + 1, D)).astype(np.float32), "ids": np.arange(n, dtype=np.int32)},
    ][i % 4]
    it = Iteration(
        stage="pso" if i < 7 else "nelder_mead",
        index=i if i < 7 else i - 7,
        x=x,
        fitness=fitness,
        weights=g.dirichlet(np.ones(n)) if n else np.zeros(0),
        failed=g.random(n) < 0.2,
        best_x=g.random(D),
        best_fitness=float(g.random()),
        n_sims=n,
        wall_time=float(g.random() * 10),
        rng_state=json.dumps(g.bit_generator.state),
        extras=extras,
    )
    return it, rssd


def same_array(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def assert_same_iteration(got: Iteration, want: Iteration) -> None:
    for name in ("stage", "index", "n_sims", "rng_state"):
        assert getattr(got, name) == getattr(want, name), name
    assert np.float64(got.best_fitness).tobytes() == np.float64(want.best_fitness).tobytes()
    assert np.float64(got.wall_time).tobytes() == np.float64(want.wall_time).tobytes()
    for name in ("x", "fitness", "weights", "failed", "best_x"):
        assert same_array(getattr(got, name), getattr(want, name)), name
    assert list(got.extras) == list(want.extras)
    for key in want.extras:
        assert same_array(got.extras[key], np.asarray(want.extras[key])), key


@pytest.fixture(autouse=True)
def commit_every_iteration(monkeypatch):
    """These tests read what each append wrote; grouped commits have their own test."""
    monkeypatch.setattr(store_writer, "COMMIT_SECONDS", 0.0)


def inputs() -> dict:
    g = np.random.default_rng(7)
    p_mw = g.random(300)
    p_mw[[3, 40, 41]] = np.nan
    return dict(
        method="pso>nelder_mead",
        seed=2**100 + 3,
        names=NAMES,
        lower=np.array([0.1, 1.0, 0.02]),
        upper=np.array([10.0, 60.0, 0.08]),
        configs={
            "plant.toml": '[plant]\nname = "Ptolemaida ΙΙΙ"\r\ndroop = 0.05 # ‰\n',
            "experiments/step+1%.toml": "[step]\n",
            ".hidden": "",
        },
        options={"n_jobs": 4, "backend": "dask", "scheduler": None, "tags": ["a", "b"]},
        fmus={"iGrGen_Hydro": g.integers(0, 256, 100_000, dtype=np.uint8).tobytes(), "empty": b""},
        data={
            "step_up": {"time": np.arange(300) * 0.02, "P_MW": p_mw},
            "step_down": {"time": np.arange(5.0), "f_Hz": np.array([50, 49.9, np.nan, 49.95, 50])},
        },
        n_experiments=E,
    )


def write_run(path, n_iter: int) -> list[tuple[Iteration, np.ndarray]]:
    written = [make_iteration(i) for i in range(n_iter)]
    with ArchiveWriter.create(path, **inputs()) as w:
        for it, rssd in written:
            w.append(it, rssd)
    return written


def check_prefix(archive: RunArchive, n: int) -> None:
    """The archive holds exactly iterations 0..n-1 of :func:`make_iteration`."""
    assert archive.n_iterations == n
    got = archive.iterations()
    assert len(got) == n
    want = [make_iteration(i) for i in range(n)]
    for g, (w, _) in zip(got, want):
        assert_same_iteration(g, w)
    ev = archive.evaluations()
    if n:
        assert same_array(ev.x, np.concatenate([w.x for w, _ in want]))
        assert same_array(ev.fitness, np.concatenate([w.fitness for w, _ in want]))
        assert same_array(ev.failed, np.concatenate([w.failed for w, _ in want]))
        assert same_array(ev.rssd, np.concatenate([r for _, r in want]))
    else:
        assert ev.x.shape == (0, D) and ev.rssd.shape == (0, E)


# ------------------------------------------------------------------ round trips


def test_iterations_and_evaluations_round_trip_bit_for_bit(tmp_path):
    path = tmp_path / "run.h5"
    write_run(path, 14)
    with RunArchive(path) as a:
        check_prefix(a, 14)
        assert a.n_evaluations == sum(SIZES[i % len(SIZES)] for i in range(14))
        assert a.status == "interrupted"
        assert a.result() is None and a.uncertainty() is None


def test_inputs_and_metadata_round_trip(tmp_path):
    path = tmp_path / "run.h5"
    write_run(path, 2)
    want = inputs()
    with RunArchive(path) as a:
        assert (a.method, a.seed, a.names) == (want["method"], want["seed"], NAMES)
        assert a.n_experiments == E
        assert same_array(a.lower, want["lower"]) and same_array(a.upper, want["upper"])
        assert a.configs == want["configs"] and list(a.configs) == list(want["configs"])
        assert a.options == want["options"]
        assert a.fmus == want["fmus"] and list(a.fmus) == list(want["fmus"])
        data = a.data
        assert list(data) == list(want["data"])
        for exp, columns in want["data"].items():
            assert list(data[exp]) == list(columns)
            for col, values in columns.items():
                assert same_array(data[exp][col], values)
        assert a.hashes == {
            "fmus": {k: hashlib.sha256(v).hexdigest() for k, v in want["fmus"].items()},
            "data": {k: data_sha256(v) for k, v in want["data"].items()},
        }


def test_data_hash_sees_one_changed_sample():
    columns = inputs()["data"]["step_up"]
    changed = {k: v.copy() for k, v in columns.items()}
    changed["P_MW"][3] = 0.0  # was NaN
    assert data_sha256(columns) != data_sha256(changed)
    assert data_sha256(columns) != data_sha256(dict(reversed(list(columns.items()))))


def test_tampered_inputs_are_refused(tmp_path):
    path = tmp_path / "run.h5"
    write_run(path, 1)
    with h5py.File(path, "r+") as f:
        f["inputs/fmus/iGrGen_Hydro"][10] ^= 1
        f["inputs/data/step_down/f_Hz"][0] = 50.5
    with RunArchive(path) as a:
        with pytest.raises(ArchiveError, match="FMU 'iGrGen_Hydro'"):
            a.fmus
        with pytest.raises(ArchiveError, match="experiment 'step_down'"):
            a.data


def _result(posterior: bool) -> EstimationResult:
    g = np.random.default_rng(3)
    post = None
    if posterior:
        samples = g.random((40, D))
        post = Uncertainty(
            names=NAMES, samples=samples, weights=g.dirichlet(np.ones(40)), mean=samples.mean(0),
            cov=np.cov(samples.T), interval=np.stack([samples.min(0), samples.max(0)], 1), level=0.95,
            method="samples", log_evidence=-123.25,
        )
    return EstimationResult(
        method="smc", names=NAMES, x=g.random(D), fun=0.125, nfev=77, nit=14, wall_time=12.5,
        stop_reason="tolerance reached: |Δf| < 1e-6", history=(), n_failed=3, uncertainty=post,
    )


@pytest.mark.parametrize("with_posterior", [True, False])
def test_finish_stores_the_result(tmp_path, with_posterior):
    path = tmp_path / "run.h5"
    written = [make_iteration(i) for i in range(3)]
    want = _result(with_posterior)
    with ArchiveWriter.create(path, **inputs()) as w:
        for it, rssd in written:
            w.append(it, rssd)
        with RunArchive(path) as live:  # a reader in the same process while writing
            assert live.status == "running" and live.n_iterations == 3 and live.result() is None
        w.finish(want)
    with RunArchive(path) as a:
        assert a.status == "finished"
        got = a.result()
        assert (got.method, got.names) == ("pso>nelder_mead", NAMES)
        for name in ("fun", "nfev", "nit", "wall_time", "stop_reason", "n_failed"):
            assert getattr(got, name) == getattr(want, name), name
        assert same_array(got.x, want.x)
        assert len(got.history) == 3
        if with_posterior:
            for name in ("samples", "weights", "mean", "cov", "interval"):
                assert same_array(getattr(got.uncertainty, name), getattr(want.uncertainty, name)), name
            assert (got.uncertainty.level, got.uncertainty.log_evidence) == (0.95, -123.25)
        else:
            assert got.uncertainty is None
        summary = a.summary()
    text = json.dumps(summary, allow_nan=False)  # strict JSON
    assert json.loads(text)["best"] == {n: float(v) for n, v in zip(NAMES, want.x)}
    assert summary["stop_reason"] == want.stop_reason and summary["n_iterations"] == 3
    assert (summary["posterior"] is not None) == with_posterior
    if with_posterior:
        assert summary["posterior"]["interval"]["Ti"] == list(want.uncertainty.interval[1])
    with pytest.raises(ArchiveError, match="finished"):
        ArchiveWriter.reopen(path)


def test_summary_of_an_unfinished_run_reports_the_best_iteration(tmp_path):
    path = tmp_path / "run.h5"
    written = write_run(path, 6)
    k = int(np.argmin([it.best_fitness for it, _ in written]))
    with RunArchive(path) as a:
        s = a.summary()
    assert s["status"] == "interrupted" and s["stop_reason"] is None
    assert s["best_fitness"] == written[k][0].best_fitness
    assert s["best"] == dict(zip(NAMES, written[k][0].best_x.tolist()))
    assert s["n_failed"] == int(sum(it.failed.sum() for it, _ in written))


# ------------------------------------------------------------------ appending and reopening


def test_reopen_appends_after_the_last_iteration(tmp_path):
    path = tmp_path / "run.h5"
    write_run(path, 4)
    with ArchiveWriter.reopen(path) as w:
        assert (w.n_iterations, w.n_evaluations) == (4, sum(SIZES[:4]))
        with RunArchive(path) as live:
            assert live.status == "running"
        for i in range(4, 9):
            assert w.append(*make_iteration(i)) == i
    with RunArchive(path) as a:
        check_prefix(a, 9)
        assert a.status == "interrupted"


def test_bad_iterations_are_refused_before_anything_is_written(tmp_path):
    path = tmp_path / "run.h5"
    with ArchiveWriter.create(path, **inputs()) as w:
        w.append(*make_iteration(0))
        it, rssd = make_iteration(1)
        with pytest.raises(ValueError, match="rssd has shape"):
            w.append(it, rssd[:, :1])
        bad = Iteration(**{**it.__dict__, "x": it.x[:, :2]})
        with pytest.raises(ValueError, match="x has shape"):
            w.append(bad, rssd)
        with pytest.raises(ValueError, match="extras"):
            objects = {"obj": np.array([{}, 1], dtype=object)}
            w.append(Iteration(**{**it.__dict__, "extras": objects}), rssd)
        w.append(it, rssd)
    with RunArchive(path) as a:
        check_prefix(a, 2)


def test_rows_past_the_last_complete_iteration_are_ignored_then_overwritten(tmp_path,
                                                                            monkeypatch):
    path = tmp_path / "run.h5"
    w = ArchiveWriter.create(path, **inputs())
    for i in range(3):
        w.append(*make_iteration(i))
    real_put = store_format.put_rows

    def failing_put(ds, start, values):  # the table row is written last: fail there
        if ds.name == "/iterations/table":
            raise OSError("disk full")
        real_put(ds, start, values)

    monkeypatch.setattr(store_format, "put_rows", failing_put)
    with pytest.raises(OSError, match="disk full"):
        w.append(*make_iteration(3))
    monkeypatch.setattr(store_format, "put_rows", real_put)
    w.close()
    with h5py.File(path, "r") as f:  # the half-written iteration's rows are in the file
        n = sum(SIZES[:3])
        assert same_array(f["evaluations/x"][n : n + SIZES[3]], make_iteration(3)[0].x)
    with RunArchive(path) as a:
        check_prefix(a, 3)
    with ArchiveWriter.reopen(path) as w:
        w.append(*make_iteration(3))
        w.append(*make_iteration(4))
    with RunArchive(path) as a:
        check_prefix(a, 5)


def _raw_ranges(path) -> list[tuple[int, int]]:
    """The bytes a live writer may change, as the seal leaves them out (fixed-size
    dataset contents and the superblock's flags)."""
    return seal.live_ranges(str(path))


def _changed_outside(before: bytes, after: bytes, ranges) -> list[int]:
    assert len(after) == len(before)
    changed = np.flatnonzero(np.frombuffer(before, "u1") != np.frombuffer(after, "u1"))
    assert changed.size  # the comparison sees the appends
    inside = np.zeros(len(before), bool)
    for lo, hi in ranges:
        inside[lo:hi] = True
    return changed[~inside[changed]].tolist()


def test_appending_changes_no_byte_of_the_file_structure(tmp_path, monkeypatch):
    """The crash-safety invariant: in place, only dataset contents are ever written."""
    monkeypatch.setattr(store_format, "INITIAL_ROOM", SMALL_ROOM)
    path = tmp_path / "run.h5"
    snapshots = 0
    with ArchiveWriter.create(path, **inputs()) as w:
        before, inode, ranges = path.read_bytes(), path.stat().st_ino, _raw_ranges(path)
        for i in range(30):
            w.append(*make_iteration(i))
            if path.stat().st_ino != inode:  # enlarged: a new file, compare against it
                before, inode, ranges = path.read_bytes(), path.stat().st_ino, _raw_ranges(path)
                snapshots += 1
            else:
                assert _changed_outside(before, path.read_bytes(), ranges) == [], i
    assert _changed_outside(before, path.read_bytes(), ranges) == []  # status 'interrupted'
    with ArchiveWriter.reopen(path) as w:  # a resumed session too
        w.append(*make_iteration(30))
    assert _changed_outside(before, path.read_bytes(), ranges) == []
    assert snapshots >= 3  # enlargements happened, and appends after them were checked


def test_enlargements_keep_everything(tmp_path, monkeypatch):
    monkeypatch.setattr(store_format, "INITIAL_ROOM", SMALL_ROOM)
    path = tmp_path / "run.h5"
    write_run(path, 40)
    with RunArchive(path) as a:
        check_prefix(a, 40)
        assert list(a.configs.items()) == list(inputs()["configs"].items())
        assert a.fmus == inputs()["fmus"] and a.hashes["data"]["step_up"] == data_sha256(
            inputs()["data"]["step_up"])
    with h5py.File(path, "r") as f:
        assert f["iterations/table"].shape[0] >= 40 > SMALL_ROOM["table"]


def test_a_finished_archive_is_cut_to_its_content(tmp_path):
    path = tmp_path / "run.h5"
    with ArchiveWriter.create(path, **inputs()) as w:
        for i in range(5):
            w.append(*make_iteration(i))
        w.finish(_result(False))
        with pytest.raises(ArchiveError, match="finished"):
            w.append(*make_iteration(5))
    n_ev = sum(SIZES[:5])
    with h5py.File(path, "r") as f:  # plain h5py sees exactly the content
        assert f["evaluations/x"].shape == (n_ev, D) and f["iterations/table"].shape == (5,)
        assert same_array(f["evaluations/rssd"][()], np.concatenate(
            [make_iteration(i)[1] for i in range(5)]))
    assert sorted(os.listdir(tmp_path)) == ["run.h5"]
    with RunArchive(path) as a:
        check_prefix(a, 5)


def test_a_failed_finish_leaves_the_run_resumable(tmp_path, monkeypatch):
    path = tmp_path / "run.h5"

    def no_space(f, result):
        raise OSError("disk full")

    monkeypatch.setattr(store_format, "write_result", no_space)
    with ArchiveWriter.create(path, **inputs()) as w:
        w.append(*make_iteration(0))
        with pytest.raises(OSError, match="disk full"):
            w.finish(_result(True))
        w.append(*make_iteration(1))
    assert sorted(os.listdir(tmp_path)) == ["run.h5"]
    with RunArchive(path) as a:
        assert a.status == "interrupted" and a.result() is None
        check_prefix(a, 2)


def test_an_empty_batch_may_come_as_flat_empty_arrays(tmp_path):
    path = tmp_path / "run.h5"
    empty = np.empty(0)
    it = Iteration("gradient", 0, empty, empty, empty, np.empty(0, bool), np.ones(D), 1.0, 0, 0.1,
                   rng_state="{}")
    with ArchiveWriter.create(path, **inputs()) as w:
        w.append(it, empty)
        w.append(*make_iteration(1))
    with RunArchive(path) as a:
        got = a.iterations()
    assert got[0].x.shape == (0, D) and got[0].stage == "gradient" and got[0].extras == {}
    assert_same_iteration(got[1], make_iteration(1)[0])


def test_a_failed_creation_leaves_nothing_behind(tmp_path):
    path = tmp_path / "run.h5"
    with pytest.raises(ValueError, match="NUL"):
        ArchiveWriter.create(path, **{**inputs(), "configs": {"bad.toml": "a\0b"}})
    assert sorted(os.listdir(tmp_path)) == []


def test_reopen_while_this_process_reads_the_archive(tmp_path):
    path = tmp_path / "run.h5"
    write_run(path, 1)
    with RunArchive(path):
        with pytest.raises(ArchiveError, match="open for reading in this process"):
            ArchiveWriter.reopen(path)
    assert not (tmp_path / "run.h5.lock").exists()
    ArchiveWriter.reopen(path).close()


def test_create_refuses_an_existing_archive(tmp_path):
    path = tmp_path / "run.h5"
    write_run(path, 1)
    with pytest.raises(ArchiveError, match="already exists"):
        ArchiveWriter.create(path, **inputs())
    assert not (tmp_path / "run.h5.lock").exists()


def test_reopen_of_a_missing_or_foreign_file(tmp_path):
    with pytest.raises(ArchiveError, match="no such archive"):
        ArchiveWriter.reopen(tmp_path / "missing.h5")
    with h5py.File(tmp_path / "other.h5", "w", libver=("v110", "v110")) as f:
        f.attrs["format"] = "something else"
    with pytest.raises(ArchiveError, match="not a rapid-cosim archive"):
        RunArchive(tmp_path / "other.h5")


# ------------------------------------------------------------------ locking


def test_a_live_writer_keeps_others_out(tmp_path):
    path = tmp_path / "run.h5"
    with ArchiveWriter.create(path, **inputs()):
        lock = json.loads((tmp_path / "run.h5.lock").read_text())
        assert (lock["pid"], lock["host"]) == (os.getpid(), socket.gethostname())
        with pytest.raises(ArchiveLocked, match=rf"{path}.*pid {os.getpid()}"):
            ArchiveWriter.reopen(path)
        with RunArchive(path) as a:  # readers need no lock
            assert a.n_iterations == 0
    assert not (tmp_path / "run.h5.lock").exists()


def test_a_lock_held_by_another_live_process_is_refused(tmp_path):
    path = tmp_path / "run.h5"
    write_run(path, 1)
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        lock = {"pid": holder.pid, "host": socket.gethostname()}
        (tmp_path / "run.h5.lock").write_text(json.dumps(lock))
        with pytest.raises(ArchiveLocked, match=rf"run.h5 is held by a live run, pid {holder.pid}"):
            ArchiveWriter.reopen(path)
    finally:
        holder.kill()
        holder.wait()
    assert (tmp_path / "run.h5.lock").exists()  # not ours to remove while it was live


def test_a_lock_from_another_host_is_refused(tmp_path):
    path = tmp_path / "run.h5"
    write_run(path, 1)
    (tmp_path / "run.h5.lock").write_text(json.dumps({"pid": 1, "host": "elsewhere.invalid"}))
    with pytest.raises(ArchiveLocked, match="pid 1 on host elsewhere.invalid"):
        ArchiveWriter.reopen(path)


def test_a_stale_lock_is_taken_over_with_a_warning(tmp_path):
    path = tmp_path / "run.h5"
    write_run(path, 2)
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    lock = {"pid": gone.pid, "host": socket.gethostname()}
    (tmp_path / "run.h5.lock").write_text(json.dumps(lock))
    with pytest.warns(UserWarning, match=rf"stale lock of pid {gone.pid}"):
        w = ArchiveWriter.reopen(path)
    with w:
        assert json.loads((tmp_path / "run.h5.lock").read_text())["pid"] == os.getpid()
        w.append(*make_iteration(2))
    assert not (tmp_path / "run.h5.lock").exists()
    with RunArchive(path) as a:
        check_prefix(a, 3)


# ------------------------------------------------------------------ kill -9

WRITER = """
import sys, time
sys.path.insert(0, {tests!r})
from test_archive_store import SMALL_ROOM, inputs, make_iteration
from rapid_cosim.archive import ArchiveWriter, format as store_format
store_format.INITIAL_ROOM = SMALL_ROOM  # enlargements (copy, rename) early and often
path, sleep = sys.argv[1], float(sys.argv[2])
w = ArchiveWriter.create(path, **inputs(), commit_seconds=0.0)  # each iteration its own commit
i = 0
while True:
    w.append(*make_iteration(i))
    i += 1
    if i == 4:
        print("committed 4", flush=True)
    if sleep:
        time.sleep(sleep)
"""


def test_kill_9_leaves_a_complete_prefix_that_can_be_resumed(tmp_path):
    script = tmp_path / "writer.py"
    script.write_text(WRITER.format(tests=str(Path(__file__).parent)))
    pick = random.Random(20240611)
    # (sleep between iterations, wait for 4 committed iterations before the random delay)
    trials = [(0.005, True), (0.005, True), (0.0, True), (0.0, True), (0.0, True), (0.0, False)]
    read = []
    for k, (sleep, wait) in enumerate(trials):
        path = tmp_path / f"run{k}.h5"
        proc = subprocess.Popen([sys.executable, str(script), str(path), str(sleep)],
                                stdout=subprocess.PIPE, text=True)
        if wait:
            assert proc.stdout.readline() == "committed 4\n"
        time.sleep(pick.uniform(0.0, 0.3))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        proc.stdout.close()
        if not path.exists():  # killed while creating: nothing half-made in its place
            assert not wait
            continue
        with RunArchive(path) as a:
            n = a.n_iterations
            assert n >= 4 or not wait
            assert a.status == "running"
            check_prefix(a, n)
            assert a.configs == inputs()["configs"] and a.fmus == inputs()["fmus"]
        read.append(n)
        # Resume: the stale lock is taken over, the file rewritten, and appending goes on.
        with pytest.warns(UserWarning) as caught:
            w = ArchiveWriter.reopen(path)
        assert [str(c.message) for c in caught] == [
            f"{path}: taking over the stale lock of pid {proc.pid}, no longer running"]
        assert sorted(os.listdir(tmp_path)) == sorted(
            [*(f"run{j}.h5" for j in range(k + 1) if (tmp_path / f"run{j}.h5").exists()),
             "run%d.h5.lock" % k, "writer.py"])  # the killed writer's side files are gone
        with w:
            w.append(*make_iteration(n))
        with RunArchive(path) as a:
            check_prefix(a, n + 1)
            assert a.status == "interrupted"
            assert list(a.configs.items()) == list(inputs()["configs"].items())
            assert list(a.data) == list(inputs()["data"]) and a.fmus == inputs()["fmus"]
    print(f"\nkill -9 trials: iterations read back {read}")


def test_readers_open_a_live_archive_at_any_moment(tmp_path):
    script = tmp_path / "writer.py"
    script.write_text(WRITER.format(tests=str(Path(__file__).parent)))
    path = tmp_path / "run.h5"
    proc = subprocess.Popen([sys.executable, str(script), str(path), "0"],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline() == "committed 4\n"
        seen = []
        for _ in range(12):  # while it appends and, with little room, enlarges
            with RunArchive(path) as a:
                check_prefix(a, a.n_iterations)
                seen.append(a.n_iterations)
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()
    assert seen[0] >= 4 and seen == sorted(seen)


# ------------------------------------------------------------------ size and speed


def test_size_and_speed_figures(tmp_path, capsys):
    path = tmp_path / "run.h5"
    g = np.random.default_rng(0)
    names = [f"p{j}" for j in range(8)]
    its = []
    for i in range(100):
        x = g.random((100, 8))
        it = Iteration("pso", i, x, g.random(100), np.full(100, 0.01), np.zeros(100, bool), x[0],
                       0.5, 100, 1.0, json.dumps(g.bit_generator.state),
                       {"velocity": g.random((100, 8))})
        its.append((it, g.random((100, 3))))
    t0 = time.perf_counter()
    with ArchiveWriter.create(path, method="pso", seed=0, names=names, lower=np.zeros(8),
                              upper=np.ones(8), configs={}, options={}, fmus={}, data={},
                              n_experiments=3) as w:
        for it, rssd in its:
            w.append(it, rssd)
        live = os.path.getsize(path) / 1e6
        w.finish(EstimationResult("pso", tuple(names), its[-1][0].best_x, 0.5, 10_000, 100, 1.0,
                                  "budget", ()))
    seconds = time.perf_counter() - t0
    with RunArchive(path) as a:
        ev = a.evaluations()
        assert same_array(ev.x, np.concatenate([it.x for it, _ in its]))
        assert same_array(ev.rssd, np.concatenate([r for _, r in its]))
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from archive_bench import bench_append

    bench = bench_append(20, 10, 4)
    assert bench["archive: file MB"] > 0 and bench["group per iteration: file MB"] > 0
    with capsys.disabled():
        size = os.path.getsize(path) / 1e6
        print(f"\narchive, 100 iterations x 100 particles (d=8, E=3): {size:.2f} MB finished "
              f"({live:.2f} MB while running), written and finished in {seconds:.2f} s "
              f"({1e3 * seconds / 100:.2f} ms per iteration, flushed)")



def test_iterations_are_committed_in_groups_and_none_is_lost_on_close(tmp_path):
    path = tmp_path / "grouped.h5"
    written = [make_iteration(i) for i in range(6)]
    with ArchiveWriter.create(path, **inputs(), commit_seconds=3600.0) as w:
        for it, rssd in written:
            w.append(it, rssd)
        assert w.n_iterations == 6
        with RunArchive(path) as live:  # the first is committed at once, the rest wait
            assert live.n_iterations == 1
        w.commit()
        with RunArchive(path) as live:
            assert live.n_iterations == 6
        w.append(*make_iteration(6))
    with RunArchive(path) as a:  # closing commits what was pending
        assert a.status == "interrupted" and a.n_iterations == 7
        check_prefix(a, 7)
