"""Appending a run's iterations to its archive (see :mod:`.format` for the layout and
why the writer never changes the structure of the live file).

Kept whole (over 400 lines): the writer's crash-safety steps are one sequence.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import time
import weakref
from datetime import datetime, timezone
from typing import Any, Mapping

import h5py
import numpy as np

from ..version import __version__
from ..errors import ArchiveDamaged, ArchiveError, ArchiveFull
from ..estimators.base import EstimationResult, Iteration
from . import format as fmt
from . import seal
from .lock import Lock

# Iterations are committed in groups, at most this many seconds apart (and when the run
# finishes or stops): one flush per group, not per iteration. A killed writer loses at
# most this much work, which a resume replays.
COMMIT_SECONDS = 0.2



def refuse_existing(path: str | os.PathLike) -> None:
    """A new run never writes over an archive: the run it holds is resumed, not restarted."""
    if os.path.exists(path):
        raise ArchiveError(f"{path} already exists: 'rapid-cosim resume {path}' finishes the run it holds "
                           "(rc.resume in Python); to start a new run, give another archive path")

class ArchiveWriter:
    """Appends the iterations of one run to its archive; use as a context manager.

    Create with :meth:`create`, or :meth:`reopen` an interrupted archive to append after
    its last complete iteration. Closing without :meth:`finish` marks the run
    'interrupted'. Only one writer per archive, across processes (see the lock above).
    """

    def __init__(self, path: str, lock: Lock, commit_seconds: float | None = None, keep: int | None = None):
        """Internal: use :meth:`create` or :meth:`reopen` (``commit_seconds``: see
        ``COMMIT_SECONDS``)."""
        self.path = path
        self._lock = lock
        self._f: h5py.File | None = None
        self.commit_seconds = COMMIT_SECONDS if commit_seconds is None else commit_seconds
        self._clear_pending()
        self._last_commit = float("-inf")  # the first iteration is committed at once
        self._keep = keep
        weakref.finalize(self, lock.release)  # a writer dropped without close() frees the lock
        self._open()

    def _open(self) -> None:
        f = self._f = fmt.open_writer(self.path)
        try:
            self._read_state(f)
        except BaseException:
            f.close()
            self._f = None
            raise

    def _read_state(self, f: h5py.File) -> None:
        self.names = tuple(f["space/names"].asstr()[()])
        self.dim = len(self.names)
        self.n_experiments = int(f.attrs["n_experiments"])
        committed = f["committed"][()]
        self._checksums = committed.shape == (3,)  # format 1 archives have none (and are resumed so)
        self._n_it, self._n_ev = (int(v) for v in committed[:2])
        truncate = self._keep is not None and self._keep < self._n_it
        if truncate:  # iterations past ``keep`` are damaged: they are computed again
            kept = f["iterations/table"][: self._keep]
            self._n_it = self._keep
            self._n_ev = int(kept[-1]["eval_offset"] + kept[-1]["eval_count"]) if len(kept) else 0
        self._ends = fmt.blob_ends(f["iterations/table"][: self._n_it])
        self._finished = fmt.status_of(f) is fmt.RunStatus.FINISHED
        self._ev = {name: f["evaluations"][name] for name in fmt.EVAL_COLUMNS}
        self._it = {name: f["iterations"][name] for name in ("table", *fmt.BLOBS)}
        self._committed = f["committed"]
        if truncate:
            self._write_committed(self._n_it, self._n_ev)
        self._room = {"evaluations": self._ev["x"].shape[0], "table": self._it["table"].shape[0],
                      **{b: self._it[b].shape[0] for b in fmt.BLOBS}}

    # ---- opening

    @classmethod
    def create(
        cls,
        path: str | os.PathLike,
        *,
        method: str,
        seed: int | None,
        names,
        lower,
        upper,
        configs: Mapping[str, str],
        options: Mapping[str, Any],
        fmus: Mapping[str, bytes],
        data: Mapping[str, Mapping[str, np.ndarray]],
        n_experiments: int,
        commit_seconds: float | None = None,
    ) -> "ArchiveWriter":
        """Start the archive of a new run; refuses an existing file (resume it instead)."""
        path = os.fspath(path)
        names = tuple(names)
        lower = np.asarray(lower, dtype="<f8")
        upper = np.asarray(upper, dtype="<f8")
        if not names or lower.shape != (len(names),) or upper.shape != lower.shape:
            raise ValueError("need at least one parameter, and one lower and upper bound per name")
        if int(n_experiments) < 1:
            raise ValueError("n_experiments must be at least 1")
        try:
            options_text = json.dumps(dict(options), sort_keys=True)
        except TypeError as exc:
            raise ValueError(f"run options must be JSON-serialisable: {exc}") from None
        lock = Lock(path)
        lock.acquire()
        try:
            refuse_existing(path)
            # Built beside and renamed into place: a crash leaves no archive or a whole one.
            tmp = path + ".creating"
            try:
                with h5py.File(tmp, "w", libver=fmt.LIBVER, track_order=True, locking=False,
                               userblock_size=seal.USERBLOCK) as f:
                    f.attrs.update(
                        format=fmt.FORMAT,
                        format_version=fmt.FORMAT_VERSION,
                        rapid_cosim_version=__version__,
                        hdf5_version=h5py.version.hdf5_version,
                        created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                        method=str(method),
                        seed="" if seed is None else str(int(seed)),
                        n_experiments=int(n_experiments),
                    )
                    f.create_dataset("status", data=np.bytes_(fmt.RunStatus.RUNNING.encode()), dtype="S16")
                    f.create_dataset("committed", data=fmt.committed_row(0, 0))
                    f["committed"].attrs["meaning"] = (
                        "[n_iterations, n_evaluations, crc] complete; ignore rows past these"
                    )
                    s = f.create_group("space")
                    s.create_dataset("names", data=list(names), dtype=h5py.string_dtype("utf-8"))
                    s.create_dataset("lower", data=lower)
                    s.create_dataset("upper", data=upper)
                    f.attrs["crc32"] = fmt.header_crc(f.attrs, names, lower, upper)
                    fmt.write_inputs(f, configs, options_text, fmus, data)
                    fmt.make_run_datasets(f, len(names), int(n_experiments), fmt.INITIAL_ROOM)
                seal.seal(tmp)
            except BaseException:
                if os.path.exists(tmp):
                    os.unlink(tmp)
                raise
            fmt.replace_durably(tmp, path)
            return cls(path, lock, commit_seconds)
        except BaseException:
            lock.release()
            raise

    @classmethod
    def reopen(cls, path: str | os.PathLike, commit_seconds: float | None = None,
               keep: int | None = None) -> "ArchiveWriter":
        """Open an unfinished archive to append after its last complete iteration (after
        iteration ``keep`` when the ones past it are damaged: they are dropped)."""
        path = os.fspath(path)
        lock = Lock(path)
        lock.acquire()
        try:
            if not os.path.exists(path):
                raise ArchiveError(f"{path}: no such archive")
            for stale in (path + ".creating", path + ".rewrite"):  # left by a killed writer
                if os.path.exists(stale):
                    os.unlink(stale)
            try:
                reason = seal.check(path)
            except seal.Unsealed:
                reason = None
            except OSError as exc:
                raise ArchiveError(f"{path}: not a readable archive ({exc})") from None
            if reason:
                raise ArchiveDamaged(path, "HDF5 structure", reason, "it cannot be resumed")
            try:
                with fmt.open_reader(path) as f:
                    fmt.check_format(f, path)
                    if fmt.status_of(f) is fmt.RunStatus.FINISHED:
                        raise ArchiveError(f"{path}: the run is finished; nothing to resume")
            except OSError as exc:
                raise ArchiveError(f"{path}: not a readable archive ({exc})") from None
            try:
                writer = cls(path, lock, commit_seconds, keep)
            except OSError as exc:
                if "already open for read" in str(exc):
                    raise ArchiveError(
                        f"{path} is open for reading in this process; "
                        "close it before reopening it for writing"
                    ) from None
                raise
            try:
                writer._set_status(fmt.RunStatus.RUNNING)
            except BaseException:
                writer._f.close()
                raise
            return writer
        except BaseException:
            lock.release()
            raise

    # ---- appending

    @property
    def n_iterations(self) -> int:
        return self._n_it + len(self._pending)

    @property
    def n_evaluations(self) -> int:
        return self._n_ev + self._pending_ev

    def append(self, it: Iteration, rssd: np.ndarray) -> int:
        """Archive one iteration and its evaluations; return its row (global) index."""
        self._check_open()
        # Convert and check everything before writing anything.
        fitness = np.asarray(it.fitness, dtype="<f8")
        if fitness.ndim != 1:
            raise ValueError(
                f"iteration {it.index} ({it.stage}): fitness must be 1-D, has shape {fitness.shape}"
            )
        n = fitness.shape[0]
        x = np.asarray(it.x, dtype="<f8")
        weights = np.asarray(it.weights, dtype="<f8")
        failed = np.asarray(it.failed, dtype=bool)
        rssd = np.asarray(rssd, dtype="<f8")
        if n == 0:  # an empty batch may come as np.empty(0)
            x = x.reshape(0, self.dim) if x.size == 0 else x
            rssd = rssd.reshape(0, self.n_experiments) if rssd.size == 0 else rssd
        best_x = np.asarray(it.best_x, dtype="<f8")
        expected = {
            "fitness": (fitness, (n,)),
            "x": (x, (n, self.dim)),
            "weights": (weights, (n,)),
            "failed": (failed, (n,)),
            "rssd": (rssd, (n, self.n_experiments)),
            "best_x": (best_x, (self.dim,)),
        }
        for name, (a, shape) in expected.items():
            if a.shape != shape:
                where = f"iteration {it.index} ({it.stage})"
                raise ValueError(f"{where}: {name} has shape {a.shape}, expected {shape}")
        stage = str(it.stage).encode("utf-8")
        if len(stage) > fmt.STAGE_BYTES:
            raise ValueError(f"stage name longer than {fmt.STAGE_BYTES} bytes: {it.stage!r}")
        if not isinstance(it.rng_state, str):
            kind = type(it.rng_state).__name__
            raise ValueError(f"iteration {it.index}: rng_state must be a string, not {kind}")
        blobs = {
            "rng_state": np.frombuffer(it.rng_state.encode("utf-8"), dtype="u1"),
            "extras": np.frombuffer(fmt.encode_extras(it.extras), dtype="u1"),
        }

        # Offsets after what is on disk and what waits to be committed.
        i, start = self._n_it + len(self._pending), self._n_ev + self._pending_ev
        row = np.zeros((), dtype=self._it["table"].dtype)
        row["stage"] = stage
        row["index"] = it.index
        row["best_fitness"] = it.best_fitness
        row["n_sims"] = it.n_sims
        row["wall_time"] = it.wall_time
        row["eval_offset"], row["eval_count"] = start, n
        row["rng_offset"], row["rng_size"] = self._ends["rng_state"] + self._pending_blobs["rng_state"], \
            blobs["rng_state"].size
        row["extras_offset"], row["extras_size"] = self._ends["extras"] + self._pending_blobs["extras"], \
            blobs["extras"].size
        row["best_x"] = best_x
        columns = {"x": x, "fitness": fitness, "failed": failed, "weights": weights,
                   "iteration": np.full(n, i, dtype="<i8"), "rssd": rssd}
        if self._checksums:
            row["crc"] = fmt.iteration_crc(row, columns, blobs["rng_state"].tobytes(), blobs["extras"].tobytes())
        self._pending.append((row, columns, blobs))
        self._pending_ev += n
        for b in fmt.BLOBS:
            self._pending_blobs[b] += blobs[b].size
        if time.monotonic() - self._last_commit >= self.commit_seconds:
            self.commit()
        return i

    def commit(self) -> None:
        """Write the iterations appended since the last commit, then count them in
        ``/committed`` (the order that makes a killed writer harmless, see above)."""
        if not self._pending:
            return
        self._check_open()
        n_it, n_ev = self._n_it + len(self._pending), self._n_ev + self._pending_ev
        need = {"evaluations": n_ev, "table": n_it}
        need.update({b: self._ends[b] + self._pending_blobs[b] for b in fmt.BLOBS})
        pending, n_ev0, ends0, n_it0 = self._pending, self._n_ev, dict(self._ends), self._n_it
        self._clear_pending()  # a failed commit drops its iterations (a resume replays them)
        with self._space_guard():
            if any(need[k] > self._room[k] for k in need):
                self._enlarge(need)
            rows = np.stack([p[0] for p in pending])
            for name in fmt.EVAL_COLUMNS:
                fmt.put_rows(self._ev[name], n_ev0, np.concatenate([p[1][name] for p in pending]))
            for b in fmt.BLOBS:
                fmt.put_rows(self._it[b], ends0[b], np.concatenate([p[2][b] for p in pending]))
            fmt.put_rows(self._it["table"], n_it0, rows)
            self._f.flush()
            self._write_committed(n_it, n_ev)
        self._n_it, self._n_ev = n_it, n_ev
        for b in fmt.BLOBS:
            self._ends[b] = need[b]

    @contextlib.contextmanager
    def _space_guard(self):
        """A full device as one :class:`ArchiveFull` that says what is kept and what next."""
        try:
            yield
        except OSError as e:
            if e.errno == errno.ENOSPC or "No space left" in str(e) or "errno = 28" in str(e):
                raise ArchiveFull(f"{self.path}: no space left on its device; the archive keeps its "
                                  f"{self._n_it} complete iterations: free space, then "
                                  f"'rapid-cosim resume {self.path}'") from None
            raise

    def _write_committed(self, n_it: int, n_ev: int) -> None:
        self._committed.write_direct(fmt.committed_row(n_it, n_ev) if self._checksums
                                     else np.array([n_it, n_ev], dtype="<i8"))
        self._f.flush()

    def _clear_pending(self) -> None:
        self._pending: list = []
        self._pending_ev = 0
        self._pending_blobs = {b: 0 for b in fmt.BLOBS}
        self._last_commit = time.monotonic()

    def finish(self, result: EstimationResult) -> None:
        """Store the final result and mark the run 'finished'; this closes the writer.

        The finished archive is written beside the live one, cut to its content, and
        renamed over it: a crash leaves either the running archive or the finished one.
        """
        self._check_open()
        if tuple(result.names) != self.names:
            raise ValueError(
                f"result names {tuple(result.names)} differ from the archive's {self.names}"
            )
        x = np.asarray(result.x, dtype="<f8")
        if x.shape != (self.dim,):
            raise ValueError(f"result x has shape {x.shape}, expected {(self.dim,)}")
        if result.uncertainty is not None:
            fmt.check_uncertainty(result.uncertainty, self.names)
        self.commit()
        self._f.close()
        self._f = None
        try:
            room = {"evaluations": self._n_ev, "table": self._n_it, **self._ends}
            with self._space_guard():
                fmt.rewrite(self.path, room, result)
        except BaseException:
            self._open()  # still the live archive; close() marks it interrupted
            raise
        self._finished = True
        self._lock.release()

    def close(self, quiet: bool = False) -> None:
        """Commit, mark the run 'interrupted' unless :meth:`finish` was called, close.
        ``quiet``: a failure here is not raised (another error is already on its way)."""
        if self._f is None:
            self._lock.release()
            return
        try:
            if not self._finished:
                self.commit()
                self._set_status(fmt.RunStatus.INTERRUPTED)
        except Exception:
            if not quiet:
                raise
        finally:
            self._f.close()
            self._f = None
            self._lock.release()

    def __enter__(self) -> "ArchiveWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(quiet=exc_type is not None)

    # ---- internals

    def _check_open(self) -> None:
        if self._finished:
            raise ArchiveError(f"{self.path}: the run is finished; cannot write to it")
        if self._f is None:
            raise ArchiveError(f"{self.path}: the writer is closed")

    def _enlarge(self, need: Mapping[str, int]) -> None:
        """Swap in a copy of the archive with room for twice what is needed now.

        Everything is enlarged at once (all grow with the iterations), so the copies
        stay few: about log2(final size / initial room).
        """
        room = {k: max(v, 2 * need[k]) for k, v in self._room.items()}
        self._f.close()
        self._f = None
        try:
            fmt.rewrite(self.path, room)
        finally:
            self._open()

    def _set_status(self, status: fmt.RunStatus) -> None:
        assert status in fmt.STATUSES, status
        self._f["status"][()] = np.bytes_(status.encode())
        self._f.flush()
