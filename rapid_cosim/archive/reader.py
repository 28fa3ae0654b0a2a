"""Reading an archive, live or finished, without a lock, and checking what is read.

Every part is read under a guard: a checksum that does not match, or anything HDF5,
JSON or numpy cannot make sense of, becomes one :class:`ArchiveDamaged` naming the
archive, the damaged part and what is still readable, never a raw exception. Archives of
format 1 carry no checksums; they are read as before, with the same guards.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
from typing import Any, NamedTuple

import numpy as np

from ..errors import ArchiveDamaged, ArchiveError
from ..estimators.base import EstimationResult, Iteration
from ..estimators.uncertainty import Uncertainty
from . import format as fmt
from . import seal


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
        if not os.path.exists(self.path):
            raise ArchiveError(f"{self.path}: no such archive")
        _not_text(self.path)
        try:
            reason = seal.check(self.path)  # before HDF5 sees the file: see .seal
        except seal.Unsealed:
            reason = None  # format 1: no seal, read as before
        except OSError as exc:
            raise ArchiveError(f"{self.path}: cannot read the file ({exc})") from None
        if reason:
            raise ArchiveDamaged(self.path, "HDF5 structure", reason, "nothing can be read from it safely")
        try:
            self._f = fmt.open_reader(self.path)
        except OSError as exc:
            if not os.path.exists(self.path):
                raise ArchiveError(f"{self.path}: no such archive") from None
            raise ArchiveDamaged(self.path, "HDF5 structure", f"the file cannot be opened: {_short(exc)}",
                                 "nothing can be read from it") from None
        try:
            with self.guard("header", "nothing can be read from it"):
                f = self._f
                fmt.check_format(f, self.path)
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
                if self.checksums and int(f.attrs["crc32"]) != fmt.header_crc(f.attrs, self.names, self.lower,
                                                                              self.upper):
                    raise _Mismatch("checksum mismatch")
            # Damage to the count or the status still leaves the inputs readable: noted here,
            # raised by what needs them.
            self.damaged: list[ArchiveDamaged] = []
            self.n_iterations = self.n_evaluations = 0
            self.status = fmt.RunStatus.UNKNOWN
            try:
                with self.guard("iteration count (/committed)", "the inputs may still be readable"):
                    # /committed first: everything it counts was flushed before it was written.
                    committed = f["committed"][()]
                    n_it, n_ev = (int(v) for v in committed[:2])
                    if self.checksums and not np.array_equal(committed, fmt.committed_row(n_it, n_ev)):
                        raise _Mismatch("checksum mismatch")
                    rows, table = f["evaluations/x"].shape[0], f["iterations/table"].shape[0]
                    if not (0 <= n_it <= table and 0 <= n_ev <= rows):
                        raise _Mismatch(f"counts {n_it}, {n_ev} exceed the stored rows")
                    self.n_iterations, self.n_evaluations = n_it, n_ev
            except ArchiveDamaged as e:
                self.damaged.append(e)
            try:
                with self.guard("status"):
                    status = fmt.status_of(f)
                    if status is None:
                        raise _Mismatch(f"unknown status {f['status'][()].decode()!r}")
                    self.status = status
            except ArchiveDamaged as e:
                self.damaged.append(e)
        except BaseException:
            self._f.close()
            raise

    @property
    def checksums(self) -> bool:
        return self.format_version >= 2

    @contextlib.contextmanager
    def guard(self, part: str, readable: str | None = None):
        """Any failure to read ``part`` as one :class:`ArchiveDamaged`."""
        try:
            yield
        except ArchiveError:
            raise
        except Exception as exc:  # HDF5, JSON, numpy and unicode errors alike: the part is damaged
            raise ArchiveDamaged(self.path, part, _short(exc), readable) from None

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> "RunArchive":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---- inputs

    @property
    def configs(self) -> dict[str, str]:
        out = {}
        with self.guard("configs"):
            items = fmt.keyed(self._f["inputs/configs"]).items()
        for key, ds in items:
            with self.guard(f"config {key!r}"):
                out[key] = self._checked_text(ds)
        return out

    @property
    def options(self) -> dict[str, Any]:
        with self.guard("run options"):
            return json.loads(self._checked_text(self._f["inputs/options"]))

    def _checked_text(self, ds) -> str:
        text = fmt.read_text(ds)
        if self.checksums and int(ds.attrs["crc32"]) != fmt.text_crc(text):
            raise _Mismatch("checksum mismatch")
        return text

    @property
    def hashes(self) -> dict[str, dict[str, str]]:
        """Stored sha256 of each FMU and of each experiment's data (see :func:`fmt.data_sha256`)."""
        with self.guard("inputs"):
            i = self._f["inputs"]
            return {
                "fmus": {k: str(ds.attrs["sha256"]) for k, ds in fmt.keyed(i["fmus"]).items()},
                "data": {k: str(g.attrs["sha256"]) for k, g in fmt.keyed(i["data"]).items()},
            }

    @property
    def fmus(self) -> dict[str, bytes]:
        """FMU files by model name, checked against their stored hashes."""
        out = {}
        with self.guard("FMUs"):
            items = fmt.keyed(self._f["inputs/fmus"]).items()
        for key, ds in items:
            with self.guard(f"FMU {key!r}"):
                raw = ds[()].tobytes()
                if hashlib.sha256(raw).hexdigest() != ds.attrs["sha256"]:
                    raise _Mismatch("does not match its stored sha256")
                out[key] = raw
        return out

    @property
    def data(self) -> dict[str, dict[str, np.ndarray]]:
        """Measured columns by experiment, checked against their stored hashes."""
        out = {}
        with self.guard("measured data"):
            items = fmt.keyed(self._f["inputs/data"]).items()
        for exp, g in items:
            with self.guard(f"data of experiment {exp!r}"):
                columns = {col: ds[()] for col, ds in fmt.keyed(g).items()}
                if fmt.data_sha256(columns) != g.attrs["sha256"]:
                    raise _Mismatch("does not match its stored sha256")
                out[exp] = columns
        return out

    # ---- run

    def evaluations(self, n: int | None = None) -> StoredEvaluations:
        """The first ``n`` evaluations (default: those of the complete iterations)."""
        n = self.n_evaluations if n is None else n
        with self.guard("evaluations"):
            ev = self._f["evaluations"]
            return StoredEvaluations(ev["x"][:n], ev["fitness"][:n], ev["failed"][:n], ev["rssd"][:n])

    def iterations(self) -> list[Iteration]:
        """The complete iterations, exactly as they were appended; a damaged one raises."""
        its, damage = self.intact_iterations()
        if damage is not None:
            raise damage
        return its

    def intact_iterations(self) -> tuple[list[Iteration], ArchiveDamaged | None]:
        """The iterations before the first damaged one, and that damage (or None)."""
        if self.damaged:  # without a trustworthy count no iteration can be vouched for
            return [], self.damaged[0]
        n = self.n_iterations
        if n == 0:
            return [], None
        with self.guard("iteration table", "the inputs may still be readable"):
            it = self._f["iterations"]
            table = it["table"][:n]
            ends = fmt.blob_ends(table)
            rng = it["rng_state"][: ends["rng_state"]].tobytes()
            extras = it["extras"][: ends["extras"]].tobytes()
            ev, n_ev = self._f["evaluations"], self.n_evaluations
            columns = {k: ev[k][:n_ev] for k in fmt.EVAL_COLUMNS}
        out: list[Iteration] = []
        for k, row in enumerate(table):
            try:
                with self.guard(f"iteration {k}", f"iterations 0 to {k - 1} are intact" if k else None):
                    out.append(self._iteration(row, columns, rng, extras))
            except ArchiveDamaged as damage:
                return out, damage
        return out, None

    def _iteration(self, row, columns, rng: bytes, extras: bytes) -> Iteration:
        a, b = int(row["eval_offset"]), int(row["eval_offset"] + row["eval_count"])
        r0, e0 = int(row["rng_offset"]), int(row["extras_offset"])
        r1, e1 = r0 + int(row["rng_size"]), e0 + int(row["extras_size"])
        if not (0 <= a <= b <= len(columns["x"]) and 0 <= r0 <= r1 <= len(rng) and 0 <= e0 <= e1 <= len(extras)):
            raise _Mismatch("its offsets point outside the stored rows")
        part = {k: v[a:b] for k, v in columns.items()}
        if self.checksums and int(row["crc"]) != fmt.iteration_crc(row, part, rng[r0:r1], extras[e0:e1]):
            raise _Mismatch("checksum mismatch")
        return Iteration(stage=row["stage"].decode("utf-8"), index=int(row["index"]), x=part["x"].copy(),
                         fitness=part["fitness"].copy(), weights=part["weights"].copy(),
                         failed=part["failed"].copy(), best_x=row["best_x"].copy(),
                         best_fitness=float(row["best_fitness"]), n_sims=int(row["n_sims"]),
                         wall_time=float(row["wall_time"]), rng_state=rng[r0:r1].decode("utf-8"),
                         extras=fmt.decode_extras(extras[e0:e1]))

    def result(self) -> EstimationResult | None:
        """The final result once the run is finished (history = the archived iterations)."""
        if self.status is not fmt.RunStatus.FINISHED:
            return None
        history = tuple(self.iterations())
        with self.guard("result", "the iterations are intact"):
            r = self._f["result"]
            if self.checksums and int(r.attrs["crc32"]) != fmt.result_crc(r):
                raise _Mismatch("checksum mismatch")
            return EstimationResult(
                method=self.method, names=self.names, x=r["x"][()], fun=float(r.attrs["fun"]),
                nfev=int(r.attrs["nfev"]), nit=int(r.attrs["nit"]), wall_time=float(r.attrs["wall_time"]),
                stop_reason=str(r.attrs["stop_reason"]), history=history, n_failed=int(r.attrs["n_failed"]),
                uncertainty=self.uncertainty(),
                failure_messages=tuple(json.loads(str(r.attrs.get("failure_messages", "[]")))))

    def uncertainty(self) -> Uncertainty | None:
        if self.status is not fmt.RunStatus.FINISHED:
            return None
        with self.guard("result"):
            if "posterior" not in self._f["result"]:
                return None
            return fmt.read_uncertainty(self._f["result/posterior"], self.names)

    def summary(self) -> dict[str, Any]:
        """A JSON-serialisable digest; for an unfinished run, the best complete iteration so
        far. Damaged parts are listed under ``damaged`` and what they hold is left out."""
        out: dict[str, Any] = {
            "path": self.path, "method": self.method, "seed": self.seed, "status": self.status,
            "created": self.created, "rapid_cosim_version": self.rapid_cosim_version,
            "n_iterations": self.n_iterations, "n_evaluations": self.n_evaluations,
            "damaged": [str(d) for d in self.damaged],
        }
        its, damage = self.intact_iterations()
        if damage is not None and damage not in self.damaged:
            out["damaged"].append(str(damage))
        result = None
        if self.status is fmt.RunStatus.FINISHED and damage is None:
            try:
                result = self.result()
            except ArchiveDamaged as e:
                out["damaged"].append(str(e))
        if result is not None:
            x, fun = result.x, result.fun
            out.update(nfev=result.nfev, nit=result.nit, wall_time=_num(result.wall_time),
                       stop_reason=result.stop_reason, n_failed=result.n_failed)
        else:
            x, fun = np.full(len(self.names), np.nan), np.nan
            done = [it for it in its if np.isfinite(it.best_fitness)]
            if done:
                best = min(done, key=lambda it: it.best_fitness)
                x, fun = best.best_x, best.best_fitness
            # n_sims counts every simulation up to its iteration: the last one's is the total
            out.update(nfev=its[-1].n_sims if its else 0, nit=len(its), wall_time=None, stop_reason=None,
                       n_failed=int(sum(int(it.failed.sum()) for it in its)))
        out["best"] = {n: _num(v) for n, v in zip(self.names, x)}
        out["best_fitness"] = _num(fun)
        post = result.uncertainty if result is not None else None
        out["posterior"] = None if post is None else {
            "n_samples": 0 if post.samples is None else int(post.samples.shape[0]),
            "mean": {n: _num(v) for n, v in zip(self.names, post.mean)},
            "std": {n: _num(v) for n, v in zip(self.names, post.std)},
            "interval": {n: [_num(lo), _num(hi)] for n, (lo, hi) in zip(self.names, post.interval)},
            "level": _num(post.level),
            "log_evidence": None if post.log_evidence is None else _num(post.log_evidence),
        }
        return out


class _Mismatch(Exception):
    """A stored checksum or count that does not match what was read."""


def _short(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return text[:160]


def _num(v) -> float | None:
    """A float for JSON: NaN and infinities (not valid JSON) become None."""
    v = float(v)
    return v if np.isfinite(v) else None


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def _not_text(path: str) -> None:
    """Refuse a text file given for an archive (a config, a CSV) as such: without HDF5's
    signature and with no NUL byte in its first 4 KB it was never an archive, and calling
    it a damaged one sends a user looking for damage."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return
    if HDF5_SIGNATURE in head[:8] or b"\x00" in head:
        return
    try:
        first = head.decode("utf-8").strip().splitlines()[0][:60] if head.strip() else "nothing"
    except UnicodeDecodeError:
        return
    raise ArchiveError(f"{path}: not an archive (the HDF5 file a run writes, e.g. results/test1/pf10+nm.h5): it is text, "
                       f"starting {first!r}")

