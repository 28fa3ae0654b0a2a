"""The archive's file format: its layout, how texts, arrays and method extras are
encoded, and the low-level writes that keep a live file whole (see "Crash safety").
The writer (``writer``), the reader (``reader``) and the lock (``lock``) build on it.

Layout (HDF5 1.8 file format, so any HDF5 >= 1.8 reads it)::

    /                      attrs: format, format_version, rapid_cosim_version, created,
                                  method, seed (decimal text), n_experiments
    /status                'running' | 'finished' | 'interrupted'  (S16, rewritten in place)
    /committed             [n_iterations, n_evaluations, crc] of complete iterations, written last
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
                           n_failed, failure_messages (JSON list; absent when none failed
                           or in archives older than it). Present once the run is finished.

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

Kept whole (over 400 lines): the layout, its encodings and its checksums change
together.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import zlib
from enum import StrEnum
from typing import Any, Mapping
from urllib.parse import quote

import h5py
import numpy as np

from ..errors import ArchiveError
from ..estimators.base import EstimationResult
from ..estimators.uncertainty import Uncertainty
from . import seal

FORMAT = "rapid-cosim-archive"
FORMAT_VERSION = 2  # 2: checksums (see "Checksums"); archives of version 1 are read without them


class RunStatus(StrEnum):
    """A run's state. The first three are what an archive's /status holds (written as these
    words, so older archives read as they are); UNKNOWN is a reader's where /status is
    damaged, UNFINISHED a calibration loaded from an archive that is not finished."""

    RUNNING = "running"
    FINISHED = "finished"
    INTERRUPTED = "interrupted"
    UNKNOWN = "unknown"
    UNFINISHED = "unfinished"


STATUSES = (RunStatus.RUNNING, RunStatus.FINISHED, RunStatus.INTERRUPTED)  # what /status may hold

LIBVER = ("earliest", "v108")  # 1.8 objects (creation order); no superblock status flags
STAGE_BYTES = 64
EVAL_COLUMNS = ("x", "fitness", "failed", "weights", "iteration", "rssd")
BLOBS = {"rng_state": "rng", "extras": "extras"}  # byte dataset -> its table fields
# Room made for a new archive; each runs out after roughly 40 iterations of 100
# particles, and every enlargement doubles it.
INITIAL_ROOM = {"evaluations": 4096, "table": 256, "rng_state": 1 << 16, "extras": 1 << 20}


def crc32(*parts: bytes) -> int:
    """CRC-32 of the parts, one after the other (zlib's: fast, and enough to detect
    damage; nothing here defends against deliberate tampering)."""
    value = 0
    for part in parts:
        value = zlib.crc32(part, value)
    return value


def text_crc(text: str) -> int:
    return crc32(text.encode("utf-8"))


def committed_row(n_it: int, n_ev: int) -> np.ndarray:
    return np.array([n_it, n_ev, crc32(np.array([n_it, n_ev], dtype="<i8").tobytes())], dtype="<i8")


def header_crc(attrs: Mapping[str, Any], names, lower, upper) -> int:
    """Checksum of the root attributes a run is defined by and of its search space."""
    fields = {k: str(attrs[k]) for k in HEADER_ATTRS if k in attrs}
    return crc32(json.dumps(fields, sort_keys=True).encode(), json.dumps(list(names)).encode(),
                 np.ascontiguousarray(lower, dtype="<f8").tobytes(), np.ascontiguousarray(upper, dtype="<f8").tobytes())


def iteration_crc(row: np.ndarray, columns: Mapping[str, np.ndarray], rng: bytes, extras: bytes) -> int:
    """Checksum of one iteration: its table row (its own crc field left out), its
    evaluation rows and its bytes of rng state and extras."""
    head = np.array(row, copy=True)
    head["crc"] = 0
    return crc32(head.tobytes(), *(np.ascontiguousarray(columns[c]).tobytes() for c in EVAL_COLUMNS), rng, extras)


HEADER_ATTRS = ("format", "format_version", "rapid_cosim_version", "created", "method", "seed", "n_experiments")


def iteration_dtype(dim: int) -> np.dtype:
    return np.dtype(
        [
            ("stage", f"S{STAGE_BYTES}"),
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
            ("crc", "<u4"),
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


def encode_extras(extras: Mapping[str, np.ndarray]) -> bytes:
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


def decode_extras(blob: bytes) -> dict[str, np.ndarray]:
    if not blob:
        return {}
    n = int.from_bytes(blob[:8], "little")
    header = json.loads(blob[8 : 8 + n])
    out, pos = {}, 8 + n
    for key, size in zip(header["keys"], header["sizes"]):
        out[key] = np.load(io.BytesIO(blob[pos : pos + size]), allow_pickle=False)
        pos += size
    return out


def child_name(key: str) -> str:
    """An HDF5 link name for a user key; the key itself is kept in the ``key`` attr."""
    if not isinstance(key, str) or not key:
        raise ValueError(
            f"names of configs, FMUs, experiments and columns must be non-empty text, not {key!r}"
        )
    name = quote(key, safe=" -_.~+,;=()[]@")
    return "%2E" + name[1:] if name.startswith(".") else name


def put_text(group: h5py.Group, key: str, text: str) -> None:
    if not isinstance(text, str) or "\0" in text:
        raise ValueError(f"{key!r}: expected text without NUL characters")
    ds = group.create_dataset(child_name(key), data=text, dtype=h5py.string_dtype("utf-8"))
    ds.attrs["key"] = key
    ds.attrs["crc32"] = text_crc(text)


def read_text(ds: h5py.Dataset) -> str:
    return ds.asstr()[()]


def keyed(group: h5py.Group) -> dict[str, Any]:
    """Children of a track-ordered group, by their original key, in creation order."""
    return {str(obj.attrs["key"]): obj for obj in group.values()}


def roomy(group: h5py.Group, name: str, dtype, rows: int, row: tuple = ()) -> h5py.Dataset:
    """A contiguous dataset whose file space is allocated now, never later."""
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_layout(h5py.h5d.CONTIGUOUS)
    dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
    return group.create_dataset(name, shape=(rows, *row), dtype=dtype, dcpl=dcpl)


def put_rows(ds: h5py.Dataset, start: int, values: np.ndarray) -> None:
    """Write ``values`` at rows ``start:`` of ``ds``.

    Low-level calls: at these sizes h5py's slicing costs more than HDF5's own work.
    """
    values = np.ascontiguousarray(values)
    if not values.shape[0]:
        return
    space = ds.id.get_space()
    space.select_hyperslab((start,) + (0,) * (values.ndim - 1), values.shape)
    ds.id.write(h5py.h5s.create_simple(values.shape), space, values)


def fsync(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def replace_durably(tmp: str, path: str) -> None:
    """Rename a complete side file over ``path``, durably."""
    fsync(tmp)
    os.replace(tmp, path)
    try:
        fsync(os.path.dirname(os.path.abspath(path)))
    except OSError:  # directories cannot be opened for fsync everywhere (Windows)
        pass


def open_writer(path: str) -> h5py.File:
    # Exclusion between writers is the lock file's job. Without HDF5's own flock, readers
    # (which open with locking off too) share the file with the writer, even in-process.
    return h5py.File(path, "r+", locking=False)


def open_reader(path: str) -> h5py.File:
    return h5py.File(path, "r", locking=False)


def blob_ends(table: np.ndarray) -> dict[str, int]:
    """Bytes used in each byte dataset by the iterations of ``table``."""
    if not len(table):
        return {blob: 0 for blob in BLOBS}
    last = table[-1]
    return {blob: int(last[f"{f}_offset"] + last[f"{f}_size"]) for blob, f in BLOBS.items()}


def write_inputs(f: h5py.File, configs, options_text, fmus, data) -> None:
    inputs = f.create_group("inputs")
    g = inputs.create_group("configs", track_order=True)
    for key, text in configs.items():
        put_text(g, key, text)
    options = inputs.create_dataset("options", data=options_text, dtype=h5py.string_dtype("utf-8"))
    options.attrs["crc32"] = text_crc(options_text)
    g = inputs.create_group("fmus", track_order=True)
    for key, blob in fmus.items():
        raw = bytes(blob)
        ds = g.create_dataset(child_name(key), data=np.frombuffer(raw, dtype="u1"))
        ds.attrs.update(key=key, sha256=hashlib.sha256(raw).hexdigest())
    g = inputs.create_group("data", track_order=True)
    for exp, columns in data.items():
        arrays = {c: np.asarray(v, dtype="<f8") for c, v in columns.items()}
        e = g.create_group(child_name(exp), track_order=True)
        e.attrs.update(key=exp, sha256=data_sha256(arrays))
        for col, values in arrays.items():
            e.create_dataset(child_name(col), data=values).attrs["key"] = col


def make_run_datasets(f: h5py.File, dim: int, n_exp: int, room: Mapping[str, int]) -> None:
    ev = f.create_group("evaluations")
    rows = room["evaluations"]
    roomy(ev, "x", "<f8", rows, (dim,))
    roomy(ev, "fitness", "<f8", rows)
    roomy(ev, "failed", bool, rows)
    roomy(ev, "weights", "<f8", rows)
    roomy(ev, "iteration", "<i8", rows)
    roomy(ev, "rssd", "<f8", rows, (n_exp,))
    it = f.create_group("iterations")
    roomy(it, "table", iteration_dtype(dim), room["table"])
    for blob in BLOBS:
        roomy(it, blob, "u1", room[blob])


def rewrite(path: str, room: Mapping[str, int], result: EstimationResult | None = None) -> None:
    """Replace the archive by a copy with the given room, finished with ``result`` if given.

    Only complete iterations are copied; the copy is renamed over ``path`` once whole.
    """
    tmp = path + ".rewrite"
    try:
        with open_reader(path) as src, h5py.File(
            tmp, "w", libver=LIBVER, track_order=True, locking=False, userblock_size=seal.USERBLOCK
        ) as dst:
            n_it, n_ev = (int(v) for v in src["committed"][()][:2])
            table = src["iterations/table"][:n_it]
            ends = blob_ends(table)
            dst.attrs.update(src.attrs)
            for name, obj in src.items():
                if name not in ("evaluations", "iterations"):
                    src.copy(obj, dst, name)
            dim, n_exp = src["evaluations/x"].shape[1], src["evaluations/rssd"].shape[1]
            make_run_datasets(dst, dim, n_exp, room)
            for name in EVAL_COLUMNS:
                put_rows(dst["evaluations"][name], 0, src["evaluations"][name][:n_ev])
            put_rows(dst["iterations/table"], 0, table)
            for b in BLOBS:
                put_rows(dst["iterations"][b], 0, src["iterations"][b][: ends[b]])
            if result is not None:
                write_result(dst, result)
                dst["status"][()] = np.bytes_(RunStatus.FINISHED.encode())
        seal.seal(tmp)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    replace_durably(tmp, path)


def write_result(f: h5py.File, result: EstimationResult) -> None:
    r = f.create_group("result")
    r.create_dataset("x", data=np.asarray(result.x, dtype="<f8"))
    r.attrs.update(
        fun=float(result.fun), nfev=int(result.nfev), nit=int(result.nit),
        wall_time=float(result.wall_time), stop_reason=str(result.stop_reason),
        n_failed=int(result.n_failed),
    )
    if result.failure_messages:
        r.attrs["failure_messages"] = json.dumps(list(result.failure_messages))
    u = result.uncertainty
    if u is not None:  # the group keeps the name it had when only SMC posteriors were stored
        p = r.create_group("posterior")
        for name in UNCERTAINTY_ARRAYS:
            if getattr(u, name) is not None:
                p.create_dataset(name, data=np.asarray(getattr(u, name), dtype="<f8"))
        p.attrs.update(level=float(u.level), method=u.method, evaluations=int(u.evaluations),
                       log_evidence=float("nan") if u.log_evidence is None else float(u.log_evidence))
    r.attrs["crc32"] = result_crc(r)


def result_crc(r: h5py.Group) -> int:
    """Checksum of the stored result: its arrays and attributes, as read back."""
    def attrs(obj) -> bytes:
        return json.dumps({k: str(v) for k, v in sorted(obj.attrs.items()) if k != "crc32"}).encode()

    parts = [attrs(r), np.ascontiguousarray(r["x"][()]).tobytes()]
    if "posterior" in r:
        p = r["posterior"]
        parts.append(attrs(p))
        parts += [name.encode() + np.ascontiguousarray(p[name][()]).tobytes() for name in sorted(p)]
    return crc32(*parts)


UNCERTAINTY_ARRAYS = ("samples", "weights", "mean", "cov", "interval", "hessian", "steps")


def check_uncertainty(u: Uncertainty, names: tuple[str, ...]) -> None:
    d = len(names)
    if tuple(u.names) != names:
        raise ValueError(f"uncertainty names {tuple(u.names)} differ from the archive's {names}")
    n = np.shape(u.samples)[0] if u.samples is not None else 0
    shapes = {"samples": (n, d), "weights": (n,), "mean": (d,), "cov": (d, d), "interval": (d, 2),
              "hessian": (d, d), "steps": (d,)}
    for name, shape in shapes.items():
        got = np.shape(getattr(u, name)) if getattr(u, name) is not None else shape
        if got != shape:
            raise ValueError(f"uncertainty {name} has shape {got}, expected {shape}")


def read_uncertainty(p, names: tuple[str, ...]) -> Uncertainty:
    """The stored uncertainty; archives made before it had a covariance stored the
    standard deviations and correlations instead."""
    arrays = {k: p[k][()] for k in UNCERTAINTY_ARRAYS if k in p}
    if "cov" not in arrays:
        std = p["std"][()]
        arrays["cov"] = np.outer(std, std) * p["corr"][()]
    log_evidence = float(p.attrs["log_evidence"])
    return Uncertainty(names, arrays["mean"], arrays["cov"], arrays["interval"], float(p.attrs["level"]),
                       str(p.attrs.get("method", "samples")), samples=arrays.get("samples"),
                       weights=arrays.get("weights"), log_evidence=log_evidence if np.isfinite(log_evidence) else None,
                       hessian=arrays.get("hessian"), steps=arrays.get("steps"),
                       evaluations=int(p.attrs.get("evaluations", 0)))


def status_of(f: h5py.File) -> RunStatus | None:
    """/status as written; None for a word no writer writes (a damaged part)."""
    word = f["status"][()].decode()
    return RunStatus(word) if word in STATUSES else None


def check_format(f: h5py.File, path: str) -> None:
    if f.attrs.get("format") != FORMAT:
        raise ArchiveError(f"{path}: not a rapid-cosim archive")
    version = int(f.attrs["format_version"])
    if version > FORMAT_VERSION:
        raise ArchiveError(
            f"{path}: archive format {version} is newer than this rapid-cosim reads "
            f"({FORMAT_VERSION})"
        )
