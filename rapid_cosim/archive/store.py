"""The HDF5 archive of one estimation run: one file per run, enough to re-run or resume
the run from the file alone.

Layout (HDF5 1.8 file format, so any HDF5 >= 1.8 reads it)::

    /                      attrs: format, format_version, rapid_cosim_version, created,
                                  method, seed (decimal text), n_experiments
    /status                'running' | 'finished' | 'interrupted'  (S16, rewritten in place)
    /committed             [n_iterations, n_evaluations] of complete iterations, written last
    /space/names, lower, upper
    /inputs/configs/<name>    TOML text, verbatim          (attr key)
    /inputs/options           run options as JSON text
    /inputs/fmus/<name>       FMU bytes as uint8            (attrs key, sha256)
    /inputs/data/<exp>/<col>  measured columns, float64     (exp attrs key, sha256)
    /iterations/table      one compound row per iteration: stage, index, best_fitness,
                           n_sims, wall_time, eval/rng/extras offsets and sizes, best_x
    /iterations/rng_state  uint8, the rng states (JSON text) end to end
    /iterations/extras     uint8, one self-describing record per iteration (see below)
    /evaluations/x, fitness, failed, weights, iteration, rssd   one row per evaluation
    /result                x, posterior/...; attrs fun, nfev, nit, wall_time, stop_reason,
                           n_failed. Present once the run is finished.

The iteration and evaluation datasets are each one set for the whole run, appended to
row by row. While a run is live they are longer than their content (see below):
``/committed`` says how many rows are complete, and a reader trusts nothing past it.
A finished archive is cut to its content, so there the lengths are the counts.

Crash safety. A process killed while HDF5 changes a file's structure can leave a file
that HDF5 cannot open at all. Measured with ``kill -9`` at random moments
(``benchmarks/archive_bench.py --crash``): a few percent of kills when a resizable
dataset is grown and flushed every iteration ("bad object header version number"), and
rarely even in SWMR mode, made for exactly this, whose readers then wait forever on a
chunk index the killed writer left half-written. So the writer never changes the
structure of the live file. Every dataset is made with room to spare (contiguous, its
file space allocated at once), and a commit only writes bytes into that room: the
evaluation rows, rng/extras bytes and table rows of the iterations appended since the
last commit, then a flush, then ``/committed``, then another flush. Commits come at most
``COMMIT_SECONDS`` apart (and when the run finishes or stops), so a fast method's many
small iterations cost one flush per group. A killed writer leaves HDF5's metadata as it was,
plus rows that ``/committed`` either counts (they were flushed before it) or does not.
(HDF5 also sets a "file open for writing" bit in the superblock while the writer has
the file open; with the version 0 superblock used here it does not act on it, so a
killed writer's archive opens as usual.) When the room runs out, the writer closes the
file, writes an enlarged copy beside it and renames the copy into place (everything
doubles at once, so this happens a few times per run); :meth:`ArchiveWriter.finish`
writes the finished archive, cut to its content, the same way. So the archive is whole
at every moment. The guarantee is against the death of the process, not of the machine
(there is no fsync per iteration).

Locking: a writer holds ``<archive>.lock``, created with O_EXCL and holding pid, host
and process start time. A lock whose process is gone from this host is taken over with
a warning; a live one raises :class:`ArchiveLocked`. Readers take no lock, and HDF5's
own file locking is off on both sides: readers may open a live archive at any moment.

Method extras (``Iteration.extras``) are free-form, so each iteration's dict is one
record: an 8-byte little-endian header length, a JSON header ``{"keys", "sizes"}``,
then one ``.npy`` image per key (``numpy.save``, no pickles), which round-trips any
non-object dtype and shape exactly.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import socket
import time
import warnings
import weakref
from datetime import datetime, timezone
from typing import Any, Mapping, NamedTuple
from urllib.parse import quote

import h5py
import numpy as np

from .. import __version__
from ..errors import ArchiveError, ArchiveLocked
from ..estimators.base import EstimationResult, Iteration, Posterior

FORMAT = "rapid-cosim-archive"
FORMAT_VERSION = 1
STATUSES = ("running", "finished", "interrupted")

_LIBVER = ("earliest", "v108")  # 1.8 objects (creation order); no superblock status flags
_STAGE_BYTES = 64
# Iterations are committed in groups, at most this many seconds apart (and when the run
# finishes or stops): one flush per group, not per iteration. A killed writer loses at
# most this much work, which a resume replays.
COMMIT_SECONDS = 0.2
_EVAL_COLUMNS = ("x", "fitness", "failed", "weights", "iteration", "rssd")
_BLOBS = {"rng_state": "rng", "extras": "extras"}  # byte dataset -> its table fields
# Room made for a new archive; each runs out after roughly 40 iterations of 100
# particles, and every enlargement doubles it.
_INITIAL_ROOM = {"evaluations": 4096, "table": 256, "rng_state": 1 << 16, "extras": 1 << 20}


def _iteration_dtype(dim: int) -> np.dtype:
    return np.dtype(
        [
            ("stage", f"S{_STAGE_BYTES}"),
            ("index", "<i8"),
            ("best_fitness", "<f8"),
            ("n_sims", "<i8"),
            ("wall_time", "<f8"),
            ("eval_offset", "<i8"),
            ("eval_count", "<i8"),
            ("rng_offset", "<i8"),
            ("rng_size", "<i8"),
            ("extras_offset", "<i8"),
            ("extras_size", "<i8"),
            ("best_x", "<f8", (dim,)),
        ]
    )


def data_sha256(columns: Mapping[str, np.ndarray]) -> str:
    """Hash of one experiment's measured columns, as stored (float64, in order).

    Covers each column's name, shape and bytes, so that renaming, reordering or
    changing a single sample (NaNs included, bit for bit) changes the hash.
    """
    h = hashlib.sha256()
    for name, values in columns.items():
        a = np.ascontiguousarray(values, dtype="<f8")
        key = name.encode("utf-8")
        h.update(len(key).to_bytes(8, "little") + key)
        h.update(json.dumps(list(a.shape)).encode() + b"\0")
        h.update(a.tobytes())
    return h.hexdigest()


def _encode_extras(extras: Mapping[str, np.ndarray]) -> bytes:
    if not extras:
        return b""
    keys, parts = [], []
    for key, value in extras.items():
        if not isinstance(key, str):
            raise ValueError(f"extras keys must be strings, got {key!r}")
        buf = io.BytesIO()
        try:
            np.save(buf, np.asarray(value), allow_pickle=False)
        except ValueError as exc:
            raise ValueError(f"extras[{key!r}] cannot be archived: {exc}") from None
        keys.append(key)
        parts.append(buf.getvalue())
    header = json.dumps({"keys": keys, "sizes": [len(p) for p in parts]}).encode()
    return len(header).to_bytes(8, "little") + header + b"".join(parts)


def _decode_extras(blob: bytes) -> dict[str, np.ndarray]:
    if not blob:
        return {}
    n = int.from_bytes(blob[:8], "little")
    header = json.loads(blob[8 : 8 + n])
    out, pos = {}, 8 + n
    for key, size in zip(header["keys"], header["sizes"]):
        out[key] = np.load(io.BytesIO(blob[pos : pos + size]), allow_pickle=False)
        pos += size
    return out


def _child_name(key: str) -> str:
    """An HDF5 link name for a user key; the key itself is kept in the ``key`` attr."""
    if not isinstance(key, str) or not key:
        raise ValueError(
            f"names of configs, FMUs, experiments and columns must be non-empty text, not {key!r}"
        )
    name = quote(key, safe=" -_.~+,;=()[]@")
    return "%2E" + name[1:] if name.startswith(".") else name


def _put_text(group: h5py.Group, key: str, text: str) -> None:
    if not isinstance(text, str) or "\0" in text:
        raise ValueError(f"{key!r}: expected text without NUL characters")
    ds = group.create_dataset(_child_name(key), data=text, dtype=h5py.string_dtype("utf-8"))
    ds.attrs["key"] = key


def _text(ds: h5py.Dataset) -> str:
    return ds.asstr()[()]


def _keyed(group: h5py.Group) -> dict[str, Any]:
    """Children of a track-ordered group, by their original key, in creation order."""
    return {str(obj.attrs["key"]): obj for obj in group.values()}


def _roomy(group: h5py.Group, name: str, dtype, rows: int, row: tuple = ()) -> h5py.Dataset:
    """A contiguous dataset whose file space is allocated now, never later."""
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_layout(h5py.h5d.CONTIGUOUS)
    dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
    return group.create_dataset(name, shape=(rows, *row), dtype=dtype, dcpl=dcpl)


def _put_rows(ds: h5py.Dataset, start: int, values: np.ndarray) -> None:
    """Write ``values`` at rows ``start:`` of ``ds``.

    Low-level calls: at these sizes h5py's slicing costs more than HDF5's own work.
    """
    values = np.ascontiguousarray(values)
    if not values.shape[0]:
        return
    space = ds.id.get_space()
    space.select_hyperslab((start,) + (0,) * (values.ndim - 1), values.shape)
    ds.id.write(h5py.h5s.create_simple(values.shape), space, values)


def _fsync(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _replace(tmp: str, path: str) -> None:
    """Rename a complete side file over ``path``, durably."""
    _fsync(tmp)
    os.replace(tmp, path)
    try:
        _fsync(os.path.dirname(os.path.abspath(path)))
    except OSError:  # directories cannot be opened for fsync everywhere (Windows)
        pass


def _open_writer(path: str) -> h5py.File:
    # Exclusion between writers is the lock file's job. Without HDF5's own flock, readers
    # (which open with locking off too) share the file with the writer, even in-process.
    return h5py.File(path, "r+", locking=False)


def _open_reader(path: str) -> h5py.File:
    return h5py.File(path, "r", locking=False)


# --------------------------------------------------------------------------- locking


def _process_start(pid: int) -> str | None:
    """Start time of ``pid`` in clock ticks since boot (Linux), to detect pid reuse."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
    except OSError:
        return None
    if fields[0] in ("Z", "X"):  # a zombie has finished running
        return "dead"
    return fields[19]


def _alive(pid: int, start: str | None) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # another user's live process
    now = _process_start(pid)
    if now == "dead":
        return False
    return start is None or now is None or now == start


class _Lock:
    """``<archive>.lock``: created with O_EXCL, removed on release."""

    GRACE = 30.0  # seconds an unreadable lock (holder died while writing it) is respected

    def __init__(self, archive: str):
        self.archive = archive
        self.path = archive + ".lock"
        pid = os.getpid()
        self.content = json.dumps(
            {"pid": pid, "host": socket.gethostname(), "start": _process_start(pid)}
        )
        self.held = False

    def acquire(self) -> None:
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                self._clear_stale()
                continue
            with os.fdopen(fd, "w") as fh:
                fh.write(self.content)
                fh.flush()
                os.fsync(fh.fileno())
            self.held = True
            return
        raise ArchiveLocked(f"{self.archive}: could not take the lock {self.path}")

    def _clear_stale(self) -> None:
        """Remove the lock if its holder is gone, else raise :class:`ArchiveLocked`."""
        try:
            with open(self.path) as fh:
                text = fh.read()
            age = time.time() - os.stat(self.path).st_mtime
        except FileNotFoundError:
            return  # released meanwhile
        try:
            holder = json.loads(text)
            pid, host = int(holder["pid"]), str(holder["host"])
        except (ValueError, KeyError, TypeError):
            if age < self.GRACE:
                raise ArchiveLocked(
                    f"{self.archive} is being opened by another process (lock {self.path})"
                ) from None
            warnings.warn(f"{self.archive}: removing unreadable lock {self.path}", stacklevel=4)
        else:
            if host != socket.gethostname():
                raise ArchiveLocked(
                    f"{self.archive} is held by pid {pid} on host {host} (lock {self.path}); "
                    "if that run is gone, delete the lock file"
                )
            if _alive(pid, holder.get("start")):
                raise ArchiveLocked(
                    f"{self.archive} is held by a live run, pid {pid} on {host} (lock {self.path})"
                )
            warnings.warn(
                f"{self.archive}: taking over the stale lock of pid {pid}, no longer running",
                stacklevel=4,
            )
        # Two processes taking over the same stale lock in the same instant could both
        # succeed; resumes of one archive are not started that way.
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass

    def release(self) -> None:
        if not self.held:
            return
        self.held = False
        try:
            with open(self.path) as fh:
                mine = fh.read() == self.content
            if mine:
                os.unlink(self.path)
        except FileNotFoundError:
            pass


# --------------------------------------------------------------------------- writing


class ArchiveWriter:
    """Appends the iterations of one run to its archive; use as a context manager.

    Create with :meth:`create`, or :meth:`reopen` an interrupted archive to append after
    its last complete iteration. Closing without :meth:`finish` marks the run
    'interrupted'. Only one writer per archive, across processes (see the lock above).
    """

    def __init__(self, path: str, lock: _Lock, commit_seconds: float | None = None):
        """Internal: use :meth:`create` or :meth:`reopen` (``commit_seconds``: see
        ``COMMIT_SECONDS``)."""
        self.path = path
        self._lock = lock
        self._f: h5py.File | None = None
        self.commit_seconds = COMMIT_SECONDS if commit_seconds is None else commit_seconds
        self._clear_pending()
        self._last_commit = float("-inf")  # the first iteration is committed at once
        weakref.finalize(self, lock.release)  # a writer dropped without close() frees the lock
        self._open()

    def _open(self) -> None:
        f = self._f = _open_writer(self.path)
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
        self._n_it, self._n_ev = (int(v) for v in f["committed"][()])
        self._ends = _blob_ends(f["iterations/table"][: self._n_it])
        self._finished = _status(f) == "finished"
        self._ev = {name: f["evaluations"][name] for name in _EVAL_COLUMNS}
        self._it = {name: f["iterations"][name] for name in ("table", *_BLOBS)}
        self._committed = f["committed"]
        self._room = {"evaluations": self._ev["x"].shape[0], "table": self._it["table"].shape[0],
                      **{b: self._it[b].shape[0] for b in _BLOBS}}

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
        lock = _Lock(path)
        lock.acquire()
        try:
            if os.path.exists(path):
                raise ArchiveError(
                    f"{path} already exists; reopen it to resume that run, or choose another path"
                )
            # Built beside and renamed into place: a crash leaves no archive or a whole one.
            tmp = path + ".creating"
            try:
                with h5py.File(tmp, "w", libver=_LIBVER, track_order=True, locking=False) as f:
                    f.attrs.update(
                        format=FORMAT,
                        format_version=FORMAT_VERSION,
                        rapid_cosim_version=__version__,
                        hdf5_version=h5py.version.hdf5_version,
                        created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                        method=str(method),
                        seed="" if seed is None else str(int(seed)),
                        n_experiments=int(n_experiments),
                    )
                    f.create_dataset("status", data=np.bytes_(b"running"), dtype="S16")
                    f.create_dataset("committed", data=np.zeros(2, dtype="<i8"))
                    f["committed"].attrs["meaning"] = (
                        "[n_iterations, n_evaluations] complete; ignore rows past these"
                    )
                    s = f.create_group("space")
                    s.create_dataset("names", data=list(names), dtype=h5py.string_dtype("utf-8"))
                    s.create_dataset("lower", data=lower)
                    s.create_dataset("upper", data=upper)
                    _write_inputs(f, configs, options_text, fmus, data)
                    _make_run_datasets(f, len(names), int(n_experiments), _INITIAL_ROOM)
            except BaseException:
                if os.path.exists(tmp):
                    os.unlink(tmp)
                raise
            _replace(tmp, path)
            return cls(path, lock, commit_seconds)
        except BaseException:
            lock.release()
            raise

    @classmethod
    def reopen(cls, path: str | os.PathLike, commit_seconds: float | None = None) -> "ArchiveWriter":
        """Open an unfinished archive to append after its last complete iteration."""
        path = os.fspath(path)
        lock = _Lock(path)
        lock.acquire()
        try:
            if not os.path.exists(path):
                raise ArchiveError(f"{path}: no such archive")
            for stale in (path + ".creating", path + ".rewrite"):  # left by a killed writer
                if os.path.exists(stale):
                    os.unlink(stale)
            try:
                with _open_reader(path) as f:
                    _check_format(f, path)
                    if _status(f) == "finished":
                        raise ArchiveError(f"{path}: the run is finished; nothing to resume")
            except OSError as exc:
                raise ArchiveError(f"{path}: not a readable archive ({exc})") from None
            try:
                writer = cls(path, lock, commit_seconds)
            except OSError as exc:
                if "already open for read" in str(exc):
                    raise ArchiveError(
                        f"{path} is open for reading in this process; "
                        "close it before reopening it for writing"
                    ) from None
                raise
            try:
                writer._set_status("running")
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
        if len(stage) > _STAGE_BYTES:
            raise ValueError(f"stage name longer than {_STAGE_BYTES} bytes: {it.stage!r}")
        if not isinstance(it.rng_state, str):
            kind = type(it.rng_state).__name__
            raise ValueError(f"iteration {it.index}: rng_state must be a string, not {kind}")
        blobs = {
            "rng_state": np.frombuffer(it.rng_state.encode("utf-8"), dtype="u1"),
            "extras": np.frombuffer(_encode_extras(it.extras), dtype="u1"),
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
        self._pending.append((row, columns, blobs))
        self._pending_ev += n
        for b in _BLOBS:
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
        need.update({b: self._ends[b] + self._pending_blobs[b] for b in _BLOBS})
        if any(need[k] > self._room[k] for k in need):
            self._enlarge(need)
        pending, n_ev0, ends0, n_it0 = self._pending, self._n_ev, dict(self._ends), self._n_it
        self._clear_pending()  # a failed commit drops its iterations (a resume replays them)
        rows = np.stack([p[0] for p in pending])
        for name in _EVAL_COLUMNS:
            _put_rows(self._ev[name], n_ev0, np.concatenate([p[1][name] for p in pending]))
        for b in _BLOBS:
            _put_rows(self._it[b], ends0[b], np.concatenate([p[2][b] for p in pending]))
        _put_rows(self._it["table"], n_it0, rows)
        self._f.flush()
        self._committed.write_direct(np.array([n_it, n_ev], dtype="<i8"))
        self._f.flush()
        self._n_it, self._n_ev = n_it, n_ev
        for b in _BLOBS:
            self._ends[b] = need[b]

    def _clear_pending(self) -> None:
        self._pending: list = []
        self._pending_ev = 0
        self._pending_blobs = {b: 0 for b in _BLOBS}
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
        if result.posterior is not None:
            _check_posterior(result.posterior, self.names)
        self.commit()
        self._f.close()
        self._f = None
        try:
            room = {"evaluations": self._n_ev, "table": self._n_it, **self._ends}
            _rewrite(self.path, room, result)
        except BaseException:
            self._open()  # still the live archive; close() marks it interrupted
            raise
        self._finished = True
        self._lock.release()

    def close(self) -> None:
        """Flush and close; the run is 'interrupted' unless :meth:`finish` was called."""
        if self._f is None:
            self._lock.release()
            return
        try:
            if not self._finished:
                self.commit()
                self._set_status("interrupted")
        finally:
            self._f.close()
            self._f = None
            self._lock.release()

    def __enter__(self) -> "ArchiveWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

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
            _rewrite(self.path, room)
        finally:
            self._open()

    def _set_status(self, status: str) -> None:
        assert status in STATUSES, status
        self._f["status"][()] = np.bytes_(status.encode())
        self._f.flush()


def _blob_ends(table: np.ndarray) -> dict[str, int]:
    """Bytes used in each byte dataset by the iterations of ``table``."""
    if not len(table):
        return {blob: 0 for blob in _BLOBS}
    last = table[-1]
    return {blob: int(last[f"{f}_offset"] + last[f"{f}_size"]) for blob, f in _BLOBS.items()}


def _write_inputs(f: h5py.File, configs, options_text, fmus, data) -> None:
    inputs = f.create_group("inputs")
    g = inputs.create_group("configs", track_order=True)
    for key, text in configs.items():
        _put_text(g, key, text)
    inputs.create_dataset("options", data=options_text, dtype=h5py.string_dtype("utf-8"))
    g = inputs.create_group("fmus", track_order=True)
    for key, blob in fmus.items():
        raw = bytes(blob)
        ds = g.create_dataset(_child_name(key), data=np.frombuffer(raw, dtype="u1"))
        ds.attrs.update(key=key, sha256=hashlib.sha256(raw).hexdigest())
    g = inputs.create_group("data", track_order=True)
    for exp, columns in data.items():
        arrays = {c: np.asarray(v, dtype="<f8") for c, v in columns.items()}
        e = g.create_group(_child_name(exp), track_order=True)
        e.attrs.update(key=exp, sha256=data_sha256(arrays))
        for col, values in arrays.items():
            e.create_dataset(_child_name(col), data=values).attrs["key"] = col


def _make_run_datasets(f: h5py.File, dim: int, n_exp: int, room: Mapping[str, int]) -> None:
    ev = f.create_group("evaluations")
    rows = room["evaluations"]
    _roomy(ev, "x", "<f8", rows, (dim,))
    _roomy(ev, "fitness", "<f8", rows)
    _roomy(ev, "failed", bool, rows)
    _roomy(ev, "weights", "<f8", rows)
    _roomy(ev, "iteration", "<i8", rows)
    _roomy(ev, "rssd", "<f8", rows, (n_exp,))
    it = f.create_group("iterations")
    _roomy(it, "table", _iteration_dtype(dim), room["table"])
    for blob in _BLOBS:
        _roomy(it, blob, "u1", room[blob])


def _rewrite(path: str, room: Mapping[str, int], result: EstimationResult | None = None) -> None:
    """Replace the archive by a copy with the given room, finished with ``result`` if given.

    Only complete iterations are copied; the copy is renamed over ``path`` once whole.
    """
    tmp = path + ".rewrite"
    try:
        with _open_reader(path) as src, h5py.File(
            tmp, "w", libver=_LIBVER, track_order=True, locking=False
        ) as dst:
            n_it, n_ev = (int(v) for v in src["committed"][()])
            table = src["iterations/table"][:n_it]
            ends = _blob_ends(table)
            dst.attrs.update(src.attrs)
            for name, obj in src.items():
                if name not in ("evaluations", "iterations"):
                    src.copy(obj, dst, name)
            dim, n_exp = src["evaluations/x"].shape[1], src["evaluations/rssd"].shape[1]
            _make_run_datasets(dst, dim, n_exp, room)
            for name in _EVAL_COLUMNS:
                _put_rows(dst["evaluations"][name], 0, src["evaluations"][name][:n_ev])
            _put_rows(dst["iterations/table"], 0, table)
            for b in _BLOBS:
                _put_rows(dst["iterations"][b], 0, src["iterations"][b][: ends[b]])
            if result is not None:
                _write_result(dst, result)
                dst["status"][()] = np.bytes_(b"finished")
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    _replace(tmp, path)


def _write_result(f: h5py.File, result: EstimationResult) -> None:
    r = f.create_group("result")
    r.create_dataset("x", data=np.asarray(result.x, dtype="<f8"))
    r.attrs.update(
        fun=float(result.fun), nfev=int(result.nfev), nit=int(result.nit),
        wall_time=float(result.wall_time), stop_reason=str(result.stop_reason),
        n_failed=int(result.n_failed),
    )
    post = result.posterior
    if post is not None:
        p = r.create_group("posterior")
        for name in ("samples", "weights", "mean", "std", "interval", "corr"):
            p.create_dataset(name, data=np.asarray(getattr(post, name), dtype="<f8"))
        p.attrs.update(level=float(post.level), log_evidence=float(post.log_evidence))


def _check_posterior(post: Posterior, names: tuple[str, ...]) -> None:
    d = len(names)
    if tuple(post.names) != names:
        raise ValueError(f"posterior names {tuple(post.names)} differ from the archive's {names}")
    samples = np.asarray(post.samples)
    n = samples.shape[0] if samples.ndim == 2 else -1
    shapes = {"samples": (n, d), "weights": (n,), "mean": (d,), "std": (d,),
              "interval": (d, 2), "corr": (d, d)}
    for name, shape in shapes.items():
        got = np.shape(getattr(post, name))
        if got != shape:
            raise ValueError(f"posterior {name} has shape {got}, expected {shape}")


def _status(f: h5py.File) -> str:
    return f["status"][()].decode()


def _check_format(f: h5py.File, path: str) -> None:
    if f.attrs.get("format") != FORMAT:
        raise ArchiveError(f"{path}: not a rapid-cosim archive")
    version = int(f.attrs["format_version"])
    if version > FORMAT_VERSION:
        raise ArchiveError(
            f"{path}: archive format {version} is newer than this rapid-cosim reads "
            f"({FORMAT_VERSION})"
        )


# --------------------------------------------------------------------------- reading


class StoredEvaluations(NamedTuple):
    """All evaluations of the complete iterations, in the order they were made."""

    x: np.ndarray  # (n, d)
    fitness: np.ndarray  # (n,)
    failed: np.ndarray  # (n,) bool
    rssd: np.ndarray  # (n, E)


class RunArchive:
    """Read-only view of an archive, live or not; takes no lock.

    The view is a snapshot: ``n_iterations`` is the number of complete iterations when it
    was opened, and nothing past them is ever returned. Open a new view to see more of
    a live run. A status of 'running' with no live writer means the writer was killed.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = os.fspath(path)
        try:
            self._f = _open_reader(self.path)
        except OSError as exc:
            raise ArchiveError(f"{self.path}: cannot open the archive ({exc})") from None
        try:
            f = self._f
            _check_format(f, self.path)
            # /committed first: everything it counts was flushed before it was written.
            self.n_iterations, self.n_evaluations = (int(v) for v in f["committed"][()])
            self.status = _status(f)
            self.format_version = int(f.attrs["format_version"])
            self.rapid_cosim_version = str(f.attrs["rapid_cosim_version"])
            self.created = str(f.attrs["created"])
            self.method = str(f.attrs["method"])
            seed = str(f.attrs["seed"])
            self.seed = int(seed) if seed else None
            self.n_experiments = int(f.attrs["n_experiments"])
            self.names = tuple(f["space/names"].asstr()[()])
            self.lower = f["space/lower"][()]
            self.upper = f["space/upper"][()]
        except BaseException:
            self._f.close()
            raise

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> "RunArchive":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- inputs

    @property
    def configs(self) -> dict[str, str]:
        return {key: _text(ds) for key, ds in _keyed(self._f["inputs/configs"]).items()}

    @property
    def options(self) -> dict[str, Any]:
        return json.loads(_text(self._f["inputs/options"]))

    @property
    def hashes(self) -> dict[str, dict[str, str]]:
        """Stored sha256 of each FMU and of each experiment's data (see :func:`data_sha256`)."""
        i = self._f["inputs"]
        return {
            "fmus": {k: str(ds.attrs["sha256"]) for k, ds in _keyed(i["fmus"]).items()},
            "data": {k: str(g.attrs["sha256"]) for k, g in _keyed(i["data"]).items()},
        }

    @property
    def fmus(self) -> dict[str, bytes]:
        """FMU files by model name, checked against their stored hashes."""
        out = {}
        for key, ds in _keyed(self._f["inputs/fmus"]).items():
            raw = ds[()].tobytes()
            if hashlib.sha256(raw).hexdigest() != ds.attrs["sha256"]:
                raise ArchiveError(f"{self.path}: FMU {key!r} does not match its stored sha256")
            out[key] = raw
        return out

    @property
    def data(self) -> dict[str, dict[str, np.ndarray]]:
        """Measured columns by experiment, checked against their stored hashes."""
        out = {}
        for exp, g in _keyed(self._f["inputs/data"]).items():
            columns = {col: ds[()] for col, ds in _keyed(g).items()}
            if data_sha256(columns) != g.attrs["sha256"]:
                raise ArchiveError(
                    f"{self.path}: data of experiment {exp!r} do not match their stored sha256"
                )
            out[exp] = columns
        return out

    # ---- run

    def evaluations(self) -> StoredEvaluations:
        ev, n = self._f["evaluations"], self.n_evaluations
        return StoredEvaluations(ev["x"][:n], ev["fitness"][:n], ev["failed"][:n], ev["rssd"][:n])

    def iterations(self) -> list[Iteration]:
        """The complete iterations, exactly as they were appended."""
        n = self.n_iterations
        if n == 0:
            return []
        it = self._f["iterations"]
        table = it["table"][:n]
        ends = _blob_ends(table)
        rng = it["rng_state"][: ends["rng_state"]].tobytes()
        extras = it["extras"][: ends["extras"]].tobytes()
        ev, n_ev = self._f["evaluations"], self.n_evaluations
        x, fitness, failed, weights = (ev[k][:n_ev] for k in ("x", "fitness", "failed", "weights"))
        out = []
        for row in table:
            a, b = int(row["eval_offset"]), int(row["eval_offset"] + row["eval_count"])
            r0, e0 = int(row["rng_offset"]), int(row["extras_offset"])
            out.append(
                Iteration(
                    stage=row["stage"].decode("utf-8"),
                    index=int(row["index"]),
                    x=x[a:b].copy(),
                    fitness=fitness[a:b].copy(),
                    weights=weights[a:b].copy(),
                    failed=failed[a:b].copy(),
                    best_x=row["best_x"].copy(),
                    best_fitness=float(row["best_fitness"]),
                    n_sims=int(row["n_sims"]),
                    wall_time=float(row["wall_time"]),
                    rng_state=rng[r0 : r0 + int(row["rng_size"])].decode("utf-8"),
                    extras=_decode_extras(extras[e0 : e0 + int(row["extras_size"])]),
                )
            )
        return out

    def result(self) -> EstimationResult | None:
        """The final result once the run is finished (history = the archived iterations)."""
        if self.status != "finished":
            return None
        r = self._f["result"]
        return EstimationResult(
            method=self.method,
            names=self.names,
            x=r["x"][()],
            fun=float(r.attrs["fun"]),
            nfev=int(r.attrs["nfev"]),
            nit=int(r.attrs["nit"]),
            wall_time=float(r.attrs["wall_time"]),
            stop_reason=str(r.attrs["stop_reason"]),
            history=tuple(self.iterations()),
            n_failed=int(r.attrs["n_failed"]),
            posterior=self.posterior(),
        )

    def posterior(self) -> Posterior | None:
        if self.status != "finished" or "posterior" not in self._f["result"]:
            return None
        p = self._f["result/posterior"]
        return Posterior(
            names=self.names,
            samples=p["samples"][()],
            weights=p["weights"][()],
            mean=p["mean"][()],
            std=p["std"][()],
            interval=p["interval"][()],
            level=float(p.attrs["level"]),
            corr=p["corr"][()],
            log_evidence=float(p.attrs["log_evidence"]),
        )

    def summary(self) -> dict[str, Any]:
        """A JSON-serialisable digest; for an unfinished run, the best iteration so far."""
        out: dict[str, Any] = {
            "path": self.path, "method": self.method, "seed": self.seed, "status": self.status,
            "created": self.created, "rapid_cosim_version": self.rapid_cosim_version,
            "n_iterations": self.n_iterations, "n_evaluations": self.n_evaluations,
        }
        if self.status == "finished":
            r = self._f["result"]
            x, fun = r["x"][()], float(r.attrs["fun"])
            out.update(
                nfev=int(r.attrs["nfev"]), nit=int(r.attrs["nit"]),
                wall_time=_num(r.attrs["wall_time"]), stop_reason=str(r.attrs["stop_reason"]),
                n_failed=int(r.attrs["n_failed"]),
            )
        else:
            table = self._f["iterations/table"][: self.n_iterations]
            failed = self._f["evaluations/failed"][: self.n_evaluations]
            x, fun = np.full(len(self.names), np.nan), np.nan
            if len(table) and not np.all(np.isnan(table["best_fitness"])):
                k = int(np.nanargmin(table["best_fitness"]))
                x, fun = table["best_x"][k], float(table["best_fitness"][k])
            out.update(nfev=int(table["n_sims"].sum()), nit=self.n_iterations,
                       wall_time=None, stop_reason=None, n_failed=int(failed.sum()))
        out["best"] = {n: _num(v) for n, v in zip(self.names, x)}
        out["best_fitness"] = _num(fun)
        post = self.posterior()
        out["posterior"] = None if post is None else {
            "n_samples": int(post.samples.shape[0]),
            "mean": {n: _num(v) for n, v in zip(self.names, post.mean)},
            "std": {n: _num(v) for n, v in zip(self.names, post.std)},
            "interval": {n: [_num(lo), _num(hi)] for n, (lo, hi) in zip(self.names, post.interval)},
            "level": _num(post.level),
            "log_evidence": _num(post.log_evidence),
        }
        return out


def _num(v) -> float | None:
    """A float for JSON: NaN and infinities (not valid JSON) become None."""
    v = float(v)
    return v if np.isfinite(v) else None
