"""Archive figures: the archive vs one HDF5 group per iteration (:func:`bench_append`),
and what a ``kill -9`` of the writer does to the file:
resizable datasets with plain flushes, the same in SWMR mode, and the archive.

    python benchmarks/archive_bench.py                      # a PSO-like and a simplex-like run
    python benchmarks/archive_bench.py --cases 500x200 --dim 8
    python benchmarks/archive_bench.py --crash 200          # kill survey, 200 kills per case
    python benchmarks/archive_bench.py --crash 50 --modes archive
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

from rapid_cosim.archive import ArchiveWriter, RunArchive
from rapid_cosim.archive.format import LIBVER as _LIBVER
from rapid_cosim.estimators.base import EstimationResult, Iteration


# ------------------------------------------------------------------ write and read

def _bench_iterations(n_iter: int, n_particles: int, d: int, n_experiments: int):
    """A synthetic PSO-like run as (Iteration, rssd) pairs, the same for the same arguments."""
    rng = np.random.default_rng(0)
    for i in range(n_iter):
        x = rng.random((n_particles, d))
        fitness = rng.random(n_particles)
        k = int(np.argmin(fitness))
        it = Iteration(
            stage="pso", index=i, x=x, fitness=fitness,
            weights=np.full(n_particles, 1 / n_particles),
            failed=rng.random(n_particles) < 0.02, best_x=x[k], best_fitness=float(fitness[k]),
            n_sims=n_particles, wall_time=1.0, rng_state=json.dumps(rng.bit_generator.state),
            extras={"velocity": rng.standard_normal((n_particles, d))},
        )
        yield it, rng.random((n_particles, n_experiments))


def bench_append(n_iter: int, n_particles: int, d: int, n_experiments: int = 3) -> dict[str, float]:
    """Time and size of a synthetic run written to this archive (flushed every iteration,
    then finished) and, for comparison, to one HDF5 group per iteration; and of reading
    it back. The archive is larger while running, by its spare room.
    """
    names = [f"p{j}" for j in range(d)]
    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "archive.h5")
        t0 = time.perf_counter()
        with ArchiveWriter.create(
            path, method="pso", seed=0, names=names, lower=np.zeros(d), upper=np.ones(d),
            configs={}, options={}, fmus={}, data={}, n_experiments=n_experiments,
        ) as w:
            for it, rssd in _bench_iterations(n_iter, n_particles, d, n_experiments):
                w.append(it, rssd)
            live = os.path.getsize(path)
            w.finish(EstimationResult("pso", tuple(names), it.best_x, it.best_fitness,
                                      n_iter * n_particles, n_iter, 0.0, "budget", ()))
        t1 = time.perf_counter()
        with RunArchive(path) as a:
            rows = sum(len(it.x) for it in a.iterations())
        t2 = time.perf_counter()
        assert rows == n_iter * n_particles
        out["archive: write ms/iteration"] = 1e3 * (t1 - t0) / n_iter
        out["archive: read s"] = t2 - t1
        out["archive: file MB"] = os.path.getsize(path) / 1e6
        out["archive: file MB while running"] = live / 1e6

        path = os.path.join(tmp, "groups.h5")
        t0 = time.perf_counter()
        with h5py.File(path, "w", libver=_LIBVER) as f:
            runs = f.create_group("iterations")
            for it, rssd in _bench_iterations(n_iter, n_particles, d, n_experiments):
                g = runs.create_group(f"{it.index:06d}")
                for name in ("x", "fitness", "weights", "failed", "best_x"):
                    g.create_dataset(name, data=getattr(it, name))
                g.create_dataset("rssd", data=rssd)
                for key, value in it.extras.items():
                    g.create_dataset(f"extras/{key}", data=value)
                g.attrs.update(stage=it.stage, index=it.index, best_fitness=it.best_fitness,
                               n_sims=it.n_sims, wall_time=it.wall_time, rng_state=it.rng_state)
                f.flush()
        t1 = time.perf_counter()
        with h5py.File(path, "r") as f:
            rows = sum(len(g["x"][()]) for g in f["iterations"].values())
        t2 = time.perf_counter()
        assert rows == n_iter * n_particles
        out["group per iteration: write ms/iteration"] = 1e3 * (t1 - t0) / n_iter
        out["group per iteration: read s"] = t2 - t1
        out["group per iteration: file MB"] = os.path.getsize(path) / 1e6
    # x, velocity, rssd, fitness, weights (float64) and failed (1 byte)
    out["payload MB"] = n_iter * n_particles * (8 * (2 * d + n_experiments + 2) + 1) / 1e6
    return {key: float(f"{value:.4g}") for key, value in out.items()}


# ------------------------------------------------------------------ kill -9 survey

_D, _E, _SIZES = 6, 3, (50, 1, 1, 5, 100)
_SURVEY_ROOM = {"evaluations": 256, "table": 8, "rng_state": 4096, "extras": 16384}
MODES = ("plain", "swmr", "archive")


def _survey_writer(path: str, mode: str, sleep: float) -> None:
    """Append iterations until killed.

    'plain' and 'swmr' grow resizable chunked datasets every iteration (flushing each
    time; 'swmr' in SWMR mode); 'archive' is :class:`ArchiveWriter`, with little room so
    that it also gets killed while enlarging.
    """
    if mode == "archive":
        from rapid_cosim.archive import format as store_format

        store_format.INITIAL_ROOM = _SURVEY_ROOM
        _write_appendable_forever(path, sleep)
        return
    f = h5py.File(path, "w", libver="earliest" if mode == "plain" else ("v110", "v110"))
    ev, it = f.create_group("ev"), f.create_group("it")
    for name, row in (("x", (_D,)), ("fitness", ()), ("rssd", (_E,))):
        ev.create_dataset(name, (0, *row), "<f8", maxshape=(None, *row), chunks=(256, *row))
    for name, dtype in (("best", "<f8"), ("offset", "<i8"), ("count", "<i8")):
        it.create_dataset(name, (0,), dtype, maxshape=(None,), chunks=(256,))
    it.create_dataset("rng", (0,), "u1", maxshape=(None,), chunks=(4096,))
    f.create_dataset("committed", data=np.zeros(1, "<i8"))
    if mode == "swmr":
        f.swmr_mode = True
    print("ready", flush=True)
    i = n_ev = 0
    while True:
        n = _SIZES[i % len(_SIZES)]
        x = np.random.default_rng(i).random((n, _D))
        for name, a in (("x", x), ("fitness", x.sum(1)), ("rssd", x[:, :_E])):
            ev[name].resize(n_ev + n, axis=0)
            ev[name][n_ev:] = a
        for name, v in (("best", x.sum(1).min()), ("offset", n_ev), ("count", n)):
            it[name].resize(i + 1, axis=0)
            it[name][i] = v
        b = np.frombuffer(json.dumps({"i": i, "pad": "x" * (i % 300)}).encode(), "u1")
        o = it["rng"].shape[0]
        it["rng"].resize(o + b.size, axis=0)
        it["rng"][o:] = b
        f.flush()
        f["committed"][0] = i + 1
        f.flush()
        i, n_ev = i + 1, n_ev + n
        if sleep:
            time.sleep(sleep)


def _write_appendable_forever(path: str, sleep: float) -> None:
    names = [f"p{j}" for j in range(_D)]
    w = ArchiveWriter.create(path, method="pso", seed=0, names=names, lower=np.zeros(_D),
                             upper=np.ones(_D), configs={"run.toml": "x = 1\n"}, options={},
                             fmus={"m": bytes(range(256)) * 64}, data={}, n_experiments=_E)
    print("ready", flush=True)
    for it, rssd in _bench_iterations(10**9, 20, _D, _E):
        w.append(it, rssd)
        if sleep:
            time.sleep(sleep)


def _survey_check(path: str, mode: str) -> int:
    """Read the killed writer's file back; raise unless it is a complete, exact prefix."""
    if mode == "archive":
        with RunArchive(path) as a:
            n = a.n_iterations
            for got, (want, rssd) in zip(a.iterations(), _bench_iterations(n, 20, _D, _E)):
                assert got.x.tobytes() == want.x.tobytes() and got.rng_state == want.rng_state
                assert got.extras["velocity"].tobytes() == want.extras["velocity"].tobytes()
            assert a.fmus["m"] == bytes(range(256)) * 64
            return n
    with h5py.File(path, "r", swmr=(mode == "swmr")) as f:
        n = int(f["committed"][0])
        x = f["ev/x"][:]
        offset, count = f["it/offset"][:n], f["it/count"][:n]
        n_ev = 0
        for i in range(n):
            k = _SIZES[i % len(_SIZES)]
            assert offset[i] == n_ev and count[i] == k
            assert np.array_equal(x[n_ev : n_ev + k], np.random.default_rng(i).random((k, _D)))
            n_ev += k
        return n


def crash_survey(mode: str, trials: int, sleep: float = 0.0, seed: int = 1) -> dict:
    """Kill a writer at ``trials`` random moments; count files that no longer read back.

    Each file is read in a separate process with a time limit: a SWMR reader facing a
    half-written structure retries without end.
    """
    pick = random.Random(seed)
    bad, errors, iterations = 0, {}, []
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "survey.h5")
        for _ in range(trials):
            for leftover in (path, path + ".lock"):
                if os.path.exists(leftover):
                    os.remove(leftover)
            proc = subprocess.Popen(
                [sys.executable, __file__, "--survey-writer", path, mode, str(sleep)],
                stdout=subprocess.PIPE, text=True,
            )
            proc.stdout.readline()
            time.sleep(pick.uniform(0.0, 1.0))
            proc.send_signal(signal.SIGKILL)
            proc.wait()
            proc.stdout.close()
            try:
                check = subprocess.run(
                    [sys.executable, __file__, "--survey-check", path, mode],
                    capture_output=True, text=True, timeout=60,
                )
                problem = check.stderr.strip().splitlines()[-1] if check.returncode else None
                if not problem:
                    iterations.append(int(check.stdout))
            except subprocess.TimeoutExpired:
                problem = "reader still waiting after 60 s"
            if problem:
                bad += 1
                errors[problem[:120]] = errors.get(problem[:120], 0) + 1
    return {"mode": mode, "sleep": sleep, "trials": trials, "unreadable": bad, "errors": errors,
            "iterations_read": [min(iterations, default=0), max(iterations, default=0)]}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--cases", default="100x100,1000x100,2000x2",
                    help="comma-separated ITERATIONSxPOINTS (default: %(default)s)")
    ap.add_argument("--dim", type=int, default=8)
    ap.add_argument("--crash", type=int, default=0, metavar="N",
                    help="kill survey with N kills per mode")
    ap.add_argument("--modes", default=",".join(MODES), help="kill survey modes: %(default)s")
    ap.add_argument("--survey-writer", nargs=3, help=argparse.SUPPRESS)
    ap.add_argument("--survey-check", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.survey_writer:
        path, mode, sleep = args.survey_writer
        _survey_writer(path, mode, float(sleep))
        return
    if args.survey_check:
        print(_survey_check(*args.survey_check))
        return
    if args.crash:
        for mode in args.modes.split(","):
            for sleep in (0.0, 0.002):
                print(json.dumps(crash_survey(mode, args.crash, sleep)), flush=True)
        return
    for case in args.cases.split(","):
        n_iter, n_points = (int(v) for v in case.lower().split("x"))
        figures = bench_append(n_iter, n_points, args.dim)
        print(f"{n_iter} iterations x {n_points} points, d={args.dim}, E=3")
        for key, value in figures.items():
            print(f"  {key:42s} {value:g}")

if __name__ == "__main__":
    main()
