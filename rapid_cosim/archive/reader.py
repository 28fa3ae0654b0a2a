"""Reading an archive, live or finished, without a lock."""

from __future__ import annotations

import hashlib
import json
import os
from typing import Any, NamedTuple

import numpy as np

from ..errors import ArchiveError
from ..estimators.base import EstimationResult, Iteration
from ..estimators.uncertainty import Uncertainty
from . import format as fmt

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
            self._f = fmt.open_reader(self.path)
        except OSError as exc:
            raise ArchiveError(f"{self.path}: cannot open the archive ({exc})") from None
        try:
            f = self._f
            fmt.check_format(f, self.path)
            # /committed first: everything it counts was flushed before it was written.
            self.n_iterations, self.n_evaluations = (int(v) for v in f["committed"][()])
            self.status = fmt.status_of(f)
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
        return {key: fmt.read_text(ds) for key, ds in fmt.keyed(self._f["inputs/configs"]).items()}

    @property
    def options(self) -> dict[str, Any]:
        return json.loads(fmt.read_text(self._f["inputs/options"]))

    @property
    def hashes(self) -> dict[str, dict[str, str]]:
        """Stored sha256 of each FMU and of each experiment's data (see :func:`fmt.data_sha256`)."""
        i = self._f["inputs"]
        return {
            "fmus": {k: str(ds.attrs["sha256"]) for k, ds in fmt.keyed(i["fmus"]).items()},
            "data": {k: str(g.attrs["sha256"]) for k, g in fmt.keyed(i["data"]).items()},
        }

    @property
    def fmus(self) -> dict[str, bytes]:
        """FMU files by model name, checked against their stored hashes."""
        out = {}
        for key, ds in fmt.keyed(self._f["inputs/fmus"]).items():
            raw = ds[()].tobytes()
            if hashlib.sha256(raw).hexdigest() != ds.attrs["sha256"]:
                raise ArchiveError(f"{self.path}: FMU {key!r} does not match its stored sha256")
            out[key] = raw
        return out

    @property
    def data(self) -> dict[str, dict[str, np.ndarray]]:
        """Measured columns by experiment, checked against their stored hashes."""
        out = {}
        for exp, g in fmt.keyed(self._f["inputs/data"]).items():
            columns = {col: ds[()] for col, ds in fmt.keyed(g).items()}
            if fmt.data_sha256(columns) != g.attrs["sha256"]:
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
        ends = fmt.blob_ends(table)
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
                    extras=fmt.decode_extras(extras[e0 : e0 + int(row["extras_size"])]),
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
            uncertainty=self.uncertainty(),
        )

    def uncertainty(self) -> Uncertainty | None:
        if self.status != "finished" or "posterior" not in self._f["result"]:
            return None
        return fmt.read_uncertainty(self._f["result/posterior"], self.names)

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
        post = self.uncertainty()
        out["posterior"] = None if post is None else {
            "n_samples": 0 if post.samples is None else int(post.samples.shape[0]),
            "mean": {n: _num(v) for n, v in zip(self.names, post.mean)},
            "std": {n: _num(v) for n, v in zip(self.names, post.std)},
            "interval": {n: [_num(lo), _num(hi)] for n, (lo, hi) in zip(self.names, post.interval)},
            "level": _num(post.level),
            "log_evidence": None if post.log_evidence is None else _num(post.log_evidence),
        }
        return out


def _num(v) -> float | None:
    """A float for JSON: NaN and infinities (not valid JSON) become None."""
    v = float(v)
    return v if np.isfinite(v) else None
