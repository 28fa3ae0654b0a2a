"""Where batches are scored: in this process, on local worker processes, or on a dask
cluster. An objective hands its engine a function, a payload and chunks of parameter
sets; the engine returns the results in the order of the chunks. No estimator and no
objective knows which engine runs it (as pyPESTO passes its engine to every method).

Every evaluation is deterministic and independent, so results do not depend on the
engine, the number of workers or the chunking.
"""

from __future__ import annotations

import functools
import numbers
import os
import threading
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol, Sequence

import numpy as np

from ..errors import EngineLost, RapidCosimError

JOBLIB_BACKENDS = ("loky", "multiprocessing", "sequential", "dask")
LOCAL_PROCESSES = ("loky", "multiprocessing")  # backends whose workers are this machine's processes


@contextmanager
def pinned_threads():
    """The BLAS and OpenMP thread pools at one thread while a run works, in this process
    and in every worker. Why: the numerical work between simulations is small matrices
    (a noise model's Cholesky factor, a Levenberg-Marquardt step), which a multi-threaded
    BLAS makes slower, not faster, once a run's processes fill the cores (a 181-sample
    Cholesky took 35 ms against 2 ms with the other core busy); and a pool's size changes
    the last bits of a sum, so a unit gave other numbers on a bare dask worker (the
    machine's threads) than on a local cluster (a nanny sets one)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield


def pinned(fn):
    """``fn`` run with :func:`pinned_threads` (what an engine sends its workers)."""
    return functools.partial(_pinned_call, fn)


def _pinned_call(fn, *args, **kwargs):
    with pinned_threads():
        return fn(*args, **kwargs)
LOST_WORKER_RETRIES = 3  # times a batch is run again on a fresh pool after a worker died
# joblib's reusable pool is one per process, and two threads making it at once can find it half made
# (joblib issue 1794): a map holds this while it runs, and a map from another thread (EngineSpec.warm) waits
_POOL = threading.RLock()


class Engine(Protocol):
    workers: int
    local: bool  # True: a batch is scored in this process, not mapped

    def map(self, fn: Callable[[Any, np.ndarray], Any], payload: Any, chunks: Sequence[np.ndarray]) -> list: ...


@dataclass
class SequentialEngine:
    """Everything in this process."""

    workers: int = 1
    local: bool = True

    def map(self, fn, payload, chunks) -> list:
        return [fn(payload, c) for c in chunks]


@dataclass
class JoblibEngine:
    """Local worker processes through joblib (``loky`` keeps its workers between calls).

    A worker that dies (killed, out of memory) breaks its pool: the batch is run again
    on a fresh pool, up to ``retries`` times, and each loss is noted in ``events`` (the
    run archives them with the iteration they happened in) and warned about.
    """

    n_jobs: int = 2
    backend: str = "loky"
    retries: int = LOST_WORKER_RETRIES
    events: list[str] = field(default_factory=list)

    @property
    def workers(self) -> int:
        import joblib

        return joblib.cpu_count() if self.n_jobs == -1 else self.n_jobs

    @property
    def local(self) -> bool:
        return self.workers == 1

    def map(self, fn, payload, chunks) -> list:
        import joblib
        from joblib.externals.loky.process_executor import BrokenProcessPool, TerminatedWorkerError

        for attempt in range(self.retries + 1):
            try:
                with _POOL, joblib.parallel_config(backend=self.backend, n_jobs=self.n_jobs):
                    return joblib.Parallel()(joblib.delayed(pinned(fn))(payload, c) for c in chunks)
            except (TerminatedWorkerError, BrokenProcessPool) as e:
                reason = str(e).strip().splitlines()[0][:200]
                if attempt == self.retries:
                    raise RapidCosimError(f"worker processes died {attempt + 1} times in one batch, the last "
                                          f"time: {reason}") from None
                event = f"a worker process died ({reason}); its batch ran again on a fresh pool"
                self.events.append(event)
                warnings.warn(event, stacklevel=2)
        raise AssertionError("unreachable")


def _ready(payload, chunk) -> int:
    """Nothing but a worker that has imported rapid_cosim (unpickling this function did)."""
    return os.getpid()


def _warm(spec: "EngineSpec", workers: list) -> None:
    try:
        workers += JoblibEngine(spec.n_jobs, spec.backend, retries=0).map(_ready, None, [np.zeros(1)] * spec.workers())
    except Exception:  # noqa: BLE001 - best effort: a pool that fails to start fails again, and says why, in the work
        pass


def _yielding() -> None:
    """A background worker's start: a lower priority than the work waited on. Nice 5
    (a third of the weight of the work waited on): on 2 workers, rapid-cosim identify took
    18.5 / 10.6 / 52.8 s on the steam, electrical and field units at nice 5, 18.9 / 11.6 /
    63.0 s at nice 10 (the field unit's long structure fits, its critical path, starved) and
    21.9 / 13.0 / 51.8 s at nice 0 (the steam unit's explanation slowed by half), measured
    with a quicker whitening since reverted (docs/studies.md)."""
    if hasattr(os, "nice"):
        os.nice(5)


class Started:
    """Chunks of work started now on worker processes of their own, collected later by
    :meth:`result`, while this process goes on with other work (an identification fits
    its standard structures while its explanation runs: the explanation's serial stretches
    and the tail of its rounds leave the cores idle, and the operating system shares them
    between the two pools). Its workers run at a lower priority (nice 5), so the work
    this process waits on goes first and this fills what it leaves; ``first`` gives the
    order chunks start in (the longest first: the last to finish sets the time). A
    separate pool, not joblib's reusable one, which may be
    resized or restarted by a :class:`JoblibEngine` map in this process meanwhile. Each
    chunk runs pinned (:func:`pinned_threads`), as every engine's chunks do, so its results
    are the same as mapped. A pool that breaks (a worker killed) gives ``None``: the caller
    then runs the work its own way. The pool is loky's whatever the engine's backend (its
    workers are this machine's processes either way); the BLAS pools are pinned by
    threadpoolctl in each chunk, as in every engine, not by environment variables."""

    def __init__(self, fn: Callable[[Any, np.ndarray], Any], payload: Any, chunks: Sequence[np.ndarray], workers: int,
                 first: Sequence[int] | None = None):
        from joblib.externals.loky import ProcessPoolExecutor

        order = list(first) if first is not None else list(range(len(chunks)))
        if sorted(order) != list(range(len(chunks))):
            raise ValueError(f"first must name each of the {len(chunks)} chunks once, got {order}")
        self._executor = ProcessPoolExecutor(max_workers=max(1, min(workers, len(chunks))), initializer=_yielding)
        self._futures = []
        try:
            futures = {k: self._executor.submit(_pinned_call, fn, payload, chunks[k]) for k in order}
        except BaseException:  # a payload that does not pickle, Ctrl-C: no pool left behind
            self._executor.shutdown(wait=True, kill_workers=True)
            raise
        self._futures = [futures[k] for k in range(len(chunks))]

    def result(self) -> list | None:
        """The chunks' results in order (waiting for them), or None where the pool broke."""
        from joblib.externals.loky.process_executor import BrokenProcessPool, TerminatedWorkerError

        try:
            return [f.result() for f in self._futures]
        except (TerminatedWorkerError, BrokenProcessPool) as e:
            warnings.warn(f"a worker process died ({str(e).strip().splitlines()[0][:200]}); "
                          "its work runs again", stacklevel=2)
            return None
        finally:
            self.close()

    def close(self) -> None:
        """Stop the pool (its unfinished work dropped): on the caller's way out, error or not.
        The futures are not cancelled first: loky's shutdown with ``kill_workers`` drops
        them itself, and a future cancelled before it makes loky's manager thread die on
        it (InvalidStateError), leaving the workers alive and the process unable to exit
        (measured: a script whose pool held 30 s tasks still ran after 200 s; without the
        cancel it ended in 5 s)."""
        self._executor.shutdown(wait=True, kill_workers=True)


@dataclass
class DaskEngine:
    """A dask.distributed cluster: the active ``Client``, or one connected to
    ``scheduler`` (``tcp://host:port``). FMUs travel by content, so workers need no
    shared file system.

    A worker lost mid-batch costs only its tasks: the scheduler runs them again on the
    others (evaluations are pure, so the result is the same). A lost scheduler ends the
    batch with :class:`EngineLost`; the run's archive then keeps what was done.
    """

    scheduler: str | None = None
    n_jobs: int = -1  # chunks per batch; 1 or -1: one per worker of the cluster
    local: bool = False  # batches always go to the cluster, even one worker's

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
        # --n-jobs defaults to 1, which on a cluster would mean one chunk per batch
        # (the workers idle but one): the cluster's size sets the parallelism then.
        if self.n_jobs > 1:
            return self.n_jobs
        return max(len(self._client().scheduler_info()["workers"]), 1)

    def map(self, fn, payload, chunks) -> list:
        client = self._client()
        try:
            # The payload (experiments, data, FMU bytes) goes with each task rather than
            # scattered once: a task whose worker died then runs again anywhere.
            futures = [client.submit(pinned(fn), payload, c, pure=False) for c in chunks]
            return client.gather(futures)
        except Exception as e:
            if client.status == "running" and "connection" not in str(e).lower():
                raise  # an error of the evaluation itself
            reason = str(e).strip().splitlines()[0][:160] if str(e).strip() else type(e).__name__
            self._close(client)
            raise EngineLost(f"lost the dask scheduler at {self.scheduler or 'the active client'} "
                             f"({reason})") from None

    def _close(self, client) -> None:
        """Close a client whose scheduler is gone (else it keeps trying to reconnect)."""
        import logging

        for name in ("distributed", "distributed.client", "distributed.utils"):  # its reconnect noise, not ours
            logging.getLogger(name).setLevel(logging.CRITICAL + 1)
        try:
            client.close(timeout=5)
        except Exception:  # already half-closed: nothing left to release
            pass
        self._connected = None


@contextmanager
def dask_client(scheduler: str | None = None, workers: int = 2):
    """A dask.distributed client of the cluster at ``scheduler``, or of a LocalCluster of
    ``workers`` processes on this machine, one thread each (as :class:`JoblibEngine`'s
    workers: a unit's numbers then do not depend on where it runs), closed on leaving."""
    from distributed import Client, LocalCluster

    cluster = None if scheduler else LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                                  dashboard_address=None)
    try:
        with Client(scheduler or cluster) as client:
            yield client
    finally:
        if cluster is not None:
            cluster.close()


@dataclass(frozen=True)
class EngineSpec:
    """Where a run's work goes, as one value the API passes down to every stage: ``n_jobs``
    workers (-1: every core; for the fleet, its units' workers), a joblib-style ``backend``
    (``loky``, ``multiprocessing``, ``sequential``, ``dask``) and, with ``dask``, the
    ``scheduler``'s address (None: the dask client already running, for batches; a local
    cluster of ``n_jobs`` workers, for the fleet's units). A value, not an engine: it travels
    to workers, and each stage makes the engine it needs from it."""

    n_jobs: int = 1
    backend: str = "loky"
    scheduler: str | None = None

    def __post_init__(self):
        if self.backend not in JOBLIB_BACKENDS:
            raise RapidCosimError(f"unknown joblib backend {self.backend!r}; choose one of "
                                  f"{', '.join(JOBLIB_BACKENDS)}")
        if isinstance(self.n_jobs, numbers.Integral) and not isinstance(self.n_jobs, bool):
            object.__setattr__(self, "n_jobs", int(self.n_jobs))
        if not isinstance(self.n_jobs, int) or isinstance(self.n_jobs, bool) or self.n_jobs == 0 or self.n_jobs < -1:
            raise RapidCosimError(f"n_jobs must be a positive number of workers or -1 (all cores), got {self.n_jobs}")
        if self.scheduler is not None and self.backend != "dask":
            raise RapidCosimError("a scheduler address needs the dask backend (--joblib-backend dask)")

    @property
    def processes(self) -> bool:
        """Whether work is spread over this machine's worker processes (a stage may then
        map whole fits, not only batches, onto them)."""
        return self.n_jobs != 1 and self.backend in LOCAL_PROCESSES

    def workers(self) -> int:
        """Workers asked for (-1: this machine's cores)."""
        import joblib

        return joblib.cpu_count() if self.n_jobs == -1 else self.n_jobs

    def overridden(self, n_jobs: int | None = None, backend: str | None = None,
                   scheduler: str | None = None) -> "EngineSpec":
        """This engine with the settings given in place of its own (an archived run resumed
        elsewhere); another backend than dask drops the scheduler."""
        backend = self.backend if backend is None else backend
        scheduler = scheduler if scheduler is not None else (self.scheduler if backend == "dask" else None)
        return EngineSpec(self.n_jobs if n_jobs is None else n_jobs, backend, scheduler)

    def single(self) -> "EngineSpec":
        """One worker, in this process: what each of the stage's own workers runs with (the
        backend kept, as the worker's archives record it)."""
        return EngineSpec(1, self.backend if self.backend in LOCAL_PROCESSES else "loky")

    def local(self) -> "EngineSpec":
        """As many local processes (loky), never the cluster: what the short steps after a
        fit run on (intervals, profiles, the report's Laplace approximation), as they
        always did."""
        return EngineSpec(self.n_jobs)

    def start(self, fn: Callable[[Any, np.ndarray], Any], payload: Any, chunks: Sequence[np.ndarray],
              first: Sequence[int] | None = None) -> Started | None:
        """``fn`` over ``chunks`` started now on a pool of its own of this engine's
        workers (:class:`Started`), where it runs on local processes; None otherwise (the
        caller maps the work when it needs it)."""
        if not self.processes or len(chunks) < 2:
            return None
        return Started(fn, payload, chunks, self.workers(), first)

    def warm(self) -> threading.Thread | None:
        """Start this engine's local workers now, in the background, so that they have
        started and imported rapid_cosim when the first map comes (a worker takes about a
        second to start, which a staged-test diagnosis otherwise waits for after fitting
        its base model). The same reusable loky pool the maps then use; None where there is none to start
        (one worker, another backend). A map from this process waits for the start (one
        map at a time holds joblib's pool). The thread ends once the workers answer; its
        ``workers`` then holds the process ids that answered (both tasks may go to one
        worker). Not a daemon: a run that fails at once waits a second for it at exit."""
        if not self.processes or self.backend != "loky":
            return None
        workers: list[int] = []
        thread = threading.Thread(target=_warm, args=(self, workers), name="rapid-cosim: starting workers")
        thread.workers = workers
        thread.start()
        return thread

    def make(self) -> Engine:
        if self.backend == "dask":
            return DaskEngine(self.scheduler, self.n_jobs)
        if self.backend == "sequential" or self.n_jobs == 1:
            return SequentialEngine()
        return JoblibEngine(self.n_jobs, self.backend)

    def client(self):
        """A dask client of the scheduler, or of a local cluster of ``n_jobs`` single-
        threaded workers (:func:`dask_client`), for work mapped unit by unit."""
        return dask_client(self.scheduler, self.workers())


@dataclass(frozen=True)
class WholeFits:
    """What a worker fitting whole models takes (the diagnosis's candidates, the standard
    structures): the ``items``, what every fit shares (``shared``), the run options (their
    engine one worker, in that process) and ``fit``, a module-level function fitting one
    item: ``fit(item, shared, options)``. The one payload shape of :func:`map_fits`."""

    fit: Callable[[Any, Any, Any], Any]
    items: tuple
    shared: Any
    options: Any


def _fit_chunk(payload: WholeFits, chunk: np.ndarray) -> list:
    return [payload.fit(payload.items[int(k)], payload.shared, payload.options) for k in chunk]


def fit_here(payload: WholeFits) -> list:
    """Every item fitted in this process, in order."""
    return _fit_chunk(payload, np.arange(len(payload.items)))


def map_fits(engine: EngineSpec, payload: WholeFits, *, first: Sequence[int] | None = None,
             start: bool = False) -> list | Started | None:
    """Whole fits over ``engine``'s workers, one item a chunk handed to whichever worker is
    free: fits differ up to fourfold in their simulations, and chunks dealt round-robin left
    a worker idle for a fifth of a round (the payload, a few MB, then travels once per
    item). The results in item order. ``start``: begun now on a pool of their own
    (:meth:`EngineSpec.start`; ``first`` the order they start in), collected by
    :func:`collected`; None where the engine has no local workers to start them on."""
    chunks = [np.array([k]) for k in range(len(payload.items))]
    if start:
        return engine.start(_fit_chunk, payload, chunks, first)
    return [r for part in engine.make().map(_fit_chunk, payload, chunks) for r in part]


def collected(started: Started) -> list | None:
    """A started :func:`map_fits`'s results in item order, or None where its pool broke."""
    parts = started.result()
    return None if parts is None else [r for part in parts for r in part]
