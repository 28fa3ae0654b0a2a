"""Where batches are scored: in this process, on local worker processes, or on a dask
cluster. An objective hands its engine a function, a payload and chunks of parameter
sets; the engine returns the results in the order of the chunks. No estimator and no
objective knows which engine runs it (as pyPESTO passes its engine to every method).

Every evaluation is deterministic and independent, so results do not depend on the
engine, the number of workers or the chunking.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Protocol, Sequence

import numpy as np

from .errors import RapidCosimError

JOBLIB_BACKENDS = ("loky", "multiprocessing", "sequential", "dask")


class Engine(Protocol):
    workers: int

    def map(self, fn: Callable[[Any, np.ndarray], Any], payload: Any, chunks: Sequence[np.ndarray]) -> list: ...


@dataclass
class SequentialEngine:
    """Everything in this process."""

    workers: int = 1

    def map(self, fn, payload, chunks) -> list:
        return [fn(payload, c) for c in chunks]


@dataclass
class JoblibEngine:
    """Local worker processes through joblib (``loky`` keeps its workers between calls)."""

    n_jobs: int = 2
    backend: str = "loky"

    @property
    def workers(self) -> int:
        import joblib

        return joblib.cpu_count() if self.n_jobs == -1 else self.n_jobs

    def map(self, fn, payload, chunks) -> list:
        import joblib

        with joblib.parallel_config(backend=self.backend, n_jobs=self.n_jobs):
            return joblib.Parallel()(joblib.delayed(fn)(payload, c) for c in chunks)


@dataclass
class DaskEngine:
    """A dask.distributed cluster: the active ``Client``, or one connected to
    ``scheduler`` (``tcp://host:port``). FMUs travel by content, so workers need no
    shared file system."""

    scheduler: str | None = None
    n_jobs: int = -1  # chunks per batch; -1: one per worker

    def _client(self):
        from distributed import Client, get_client

        if self.scheduler is None:
            try:
                return get_client()
            except ValueError:
                raise RapidCosimError("the dask engine needs a running dask.distributed Client, or a scheduler "
                                      "address (--scheduler tcp://HOST:PORT)") from None
        client = getattr(self, "_connected", None)
        if client is None or client.status != "running":
            client = self._connected = Client(self.scheduler, timeout=30)
        return client

    @property
    def workers(self) -> int:
        if self.n_jobs > 0:
            return self.n_jobs
        return max(len(self._client().scheduler_info()["workers"]), 1)

    def map(self, fn, payload, chunks) -> list:
        client = self._client()
        kept = getattr(self, "_scattered", None)
        if kept is None or kept[0] is not payload or kept[1] is not client:
            # the payload (experiments, data, FMU bytes) goes to every worker once per run
            kept = self._scattered = (payload, client, client.scatter(payload, broadcast=True))
        futures = [client.submit(fn, kept[2], c, pure=False) for c in chunks]
        return client.gather(futures)


def make_engine(n_jobs: int = 1, backend: str = "loky", scheduler: str | None = None) -> Engine:
    """The engine for ``n_jobs`` workers of a joblib-style ``backend`` name (what the
    CLI's ``--n-jobs``, ``--joblib-backend`` and ``--scheduler`` say)."""
    if backend not in JOBLIB_BACKENDS:
        raise RapidCosimError(f"unknown joblib backend {backend!r}; choose one of {', '.join(JOBLIB_BACKENDS)}")
    if n_jobs == 0 or n_jobs < -1:
        raise RapidCosimError(f"n_jobs must be a positive number of workers or -1 (all cores), got {n_jobs}")
    if scheduler is not None and backend != "dask":
        raise RapidCosimError("a scheduler address needs the dask backend (--joblib-backend dask)")
    if backend == "dask":
        return DaskEngine(scheduler, n_jobs)
    if backend == "sequential" or n_jobs == 1:
        return SequentialEngine()
    return JoblibEngine(n_jobs, backend)
