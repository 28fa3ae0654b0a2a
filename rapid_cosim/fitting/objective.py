"""The objective every estimator calls: many parameter sets scored against a problem.

Each row of ``X`` is simulated for every experiment of the problem and scored (RSSD per
experiment, ARSSD overall). The rows go to the :mod:`engine <rapid_cosim.fitting.engine>` the
objective was given, in one chunk per worker; each worker keeps its own simulators
(:func:`rapid_cosim.simulator.get_simulator`), so no FMU is loaded per particle, and
simulates its chunk as one batch per experiment.

A simulation that fails (solver error, time-out, a non-finite output) gives the row a
fixed penalty fitness and ``failed=True``; the run goes on.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .engine import Engine, SequentialEngine
from .search import Evaluations
from ..experiment import Experiment
from .problem import Problem
from .fitness import ExperimentFit, arssd, batch_scores, combination_weights, experiment_fitness
from ..simulator import DEFAULT_RUNNER, FmuRef, Trajectory, check_runner, get_simulator

PENALTY = 1.0  # pu^2: ~10^4 times a poor fit of a 0.08 pu step, finite for every method


@dataclass(frozen=True)
class Payload:
    """What a worker needs to score rows: experiments (with data), FMUs by content and
    the runner that simulates them."""

    experiments: tuple[Experiment, ...]
    fmus: tuple[FmuRef, ...]  # one per experiment
    assignments: tuple[tuple[tuple[str, int], ...], ...]
    runner: str = DEFAULT_RUNNER


@dataclass
class FailureLog:
    """Failures seen so far: counted, and the first few messages kept for the report."""

    count: int = 0
    messages: list[str] = field(default_factory=list)

    def add(self, message: str, keep: int = 20) -> None:
        self.count += 1
        if len(self.messages) < keep:
            self.messages.append(message)


def simulate_experiment(exp: Experiment, fmu: FmuRef | str, params: Mapping[str, float], *,
                        fine: bool = False, runner: str | None = None) -> Trajectory:
    """Outputs at the measured samples inside the fitness window (what the fitness
    scores, with nothing interpolated), or on the config's fine grid for plots."""
    s = exp.simulation
    sim = get_simulator(fmu, timeout=s.timeout)
    if fine:
        return sim.simulate(params, start_time=s.start_time, stop_time=s.stop_time,
                            output_interval=s.output_interval, outputs=list(exp.outputs), runner=runner,
                            inputs=exp.input_table, communication_step=s.communication_step)
    return sim.simulate(params, start_time=s.start_time, output_times=exp.windowed_data().time,
                        outputs=list(exp.outputs), runner=runner, inputs=exp.input_table,
                        communication_step=s.communication_step)


class ExperimentBatch:
    """One experiment's simulations at the measured samples inside its fitness window,
    prepared once: each call maps search points to parameter values and runs them."""

    def __init__(self, exp: Experiment, fmu: FmuRef | str, assignment, runner: str | None = None):
        self.exp = exp
        self.fixed = np.array(list(exp.fixed.values()), dtype=float)
        self.columns = [j for _, j in assignment]
        s = exp.simulation
        self.prepared = get_simulator(fmu, timeout=s.timeout).prepare(
            list(exp.fixed) + [name for name, _ in assignment], start_time=s.start_time,
            output_times=exp.windowed_data().time, outputs=list(exp.outputs), runner=runner,
            inputs=exp.input_table, communication_step=s.communication_step)

    def __call__(self, X: np.ndarray):
        values = np.empty((X.shape[0], self.fixed.size + len(self.columns)))
        values[:, :self.fixed.size] = self.fixed
        values[:, self.fixed.size:] = X[:, self.columns]
        return self.prepared.run(values)


def _score_chunk(payload: Payload, X: np.ndarray, batches: list[ExperimentBatch] | None = None,
                 residuals: bool = False) -> tuple:
    """Worker: (rssd (n, E), failed (n,), failure messages), and with ``residuals`` the
    residual rows of each experiment (:func:`~rapid_cosim.fitting.fitness.batch_residuals`, NaN
    for a failed set). A set that fails in one experiment is not simulated in the next.
    ``batches`` are the prepared experiments when the caller keeps them (in-process
    calls); a worker prepares its own."""
    if batches is None:
        batches = _prepare(payload)
    n, n_exp = X.shape[0], len(payload.experiments)
    rssd = np.full((n, n_exp), np.inf)
    failed = np.zeros(n, dtype=bool)
    messages: list[str] = []
    blocks = [np.full((n, sum(ix.size for _, ix, _ in e.scored.columns)), np.nan) for e in payload.experiments] \
        if residuals else None
    alive = np.arange(n)
    for i, exp in enumerate(payload.experiments):
        if not alive.size:
            break
        batch = batches[i](X[alive])
        scores, rows = batch_scores(exp, batch.values, residuals)
        ok = batch.ok & np.isfinite(scores)
        if residuals and ok.any():
            blocks[i][alive[ok]] = rows[ok]
        if ok.all():
            rssd[alive, i] = scores
            continue
        rssd[alive[ok], i] = scores[ok]
        for k in np.flatnonzero(~ok):
            messages.append(f"{exp.name}: {batch.messages[k] or 'the simulated output is not finite at scored samples'}")
        failed[alive[~ok]] = True
        alive = alive[ok]
    rssd[failed] = np.inf
    if residuals:
        return rssd, failed, messages, blocks
    return rssd, failed, messages


def _prepare(payload: Payload) -> list[ExperimentBatch]:
    return [ExperimentBatch(exp, payload.fmus[i], payload.assignments[i], payload.runner)
            for i, exp in enumerate(payload.experiments)]


class ProblemObjective:
    """The :class:`~rapid_cosim.estimators.base.Objective` of a :class:`Problem`: it scores,
    and its ``engine`` decides where."""

    def __init__(self, problem: Problem, fmus: Mapping[str, FmuRef], *, engine: Engine | None = None,
                 penalty: float = PENALTY, runner: str = DEFAULT_RUNNER):
        missing = [e.model for e in problem.experiments if e.model not in fmus]
        if missing:
            raise ValueError(f"no FMU given for model(s) {', '.join(sorted(set(missing)))}")
        self.problem = problem
        self.engine = engine if engine is not None else SequentialEngine()
        self.penalty = float(penalty)
        self.payload = Payload(problem.experiments, tuple(fmus[e.model] for e in problem.experiments),
                               problem.assignments, check_runner(runner))
        self.failures = FailureLog()
        self.weights = combination_weights(problem.experiments)  # None: the paper's plain ARSSD
        self._batches: list[ExperimentBatch] | None = None  # prepared once for in-process calls
        self.n_evaluations = 0
        self.simulation_seconds = 0.0  # wall time spent inside evaluation calls

    def __call__(self, X: np.ndarray) -> Evaluations:
        return self._evaluate(X, residuals=False)[0]

    def residuals(self, X: np.ndarray) -> tuple[Evaluations, np.ndarray]:
        """The evaluations and, per row, the residual vector over all experiments whose
        squares sum to the row's fitness (whitened for whitened experiments; NaN rows for
        failed sets): what a least-squares method needs."""
        ev, blocks = self._evaluate(X, residuals=True)
        scale = np.ones(len(blocks)) / len(blocks) if self.weights is None else self.weights / self.weights.sum()
        return ev, np.concatenate([b * np.sqrt(w) for b, w in zip(blocks, scale)], axis=1)

    def residual_blocks(self, X: np.ndarray) -> list[np.ndarray]:
        """Per experiment, its residual rows (sets x valid samples) as its own fitness
        scores them (whitened for whitened experiments), unscaled by the combination."""
        return self._evaluate(X, residuals=True)[1]

    def _evaluate(self, X: np.ndarray, residuals: bool):
        X = np.atleast_2d(np.asarray(X, dtype=float))
        t0 = time.perf_counter()
        rssd, failed, messages, *blocks = self._score(X, residuals)
        self.simulation_seconds += time.perf_counter() - t0
        self.n_evaluations += X.shape[0]
        for m in messages:
            self.failures.add(m)
        fitness = np.where(failed, self.penalty, arssd(rssd, self.weights))
        return Evaluations(fitness, rssd, failed), (blocks[0] if blocks else None)

    def _score(self, X: np.ndarray, residuals: bool = False):
        # One row (a Nelder-Mead step) is scored here: shipping the payload would cost more.
        if X.shape[0] == 1 or self.engine.local:
            if self._batches is None:
                self._batches = _prepare(self.payload)
            return _score_chunk(self.payload, X, self._batches, residuals)
        chunks = [c for c in np.array_split(np.arange(X.shape[0]), min(self.engine.workers, X.shape[0])) if c.size]
        parts = self.engine.map(functools.partial(_score_chunk, residuals=residuals) if residuals else _score_chunk,
                                self.payload, [X[c] for c in chunks])
        out = (np.vstack([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
               [m for p in parts for m in p[2]])
        if residuals:
            out += ([np.vstack([p[3][i] for p in parts]) for i in range(len(self.payload.experiments))],)
        return out


@dataclass(frozen=True)
class ExperimentResult:
    """One experiment simulated at one parameter set, with its fit: what reports plot."""

    experiment: Experiment
    parameters: dict[str, float]
    trajectory: Trajectory
    fit: ExperimentFit


def evaluate_in_detail(problem: Problem, fmus: Mapping[str, FmuRef], x: np.ndarray,
                       runner: str | None = None) -> list[ExperimentResult]:
    """Trajectories and residuals at ``x`` for every experiment (in this process)."""
    return [evaluate_one(problem, fmus, x, i, runner) for i in range(len(problem.experiments))]


def evaluate_one(problem: Problem, fmus: Mapping[str, FmuRef], x: np.ndarray, i: int,
                 runner: str | None = None) -> ExperimentResult:
    """Experiment ``i``'s trajectory and residuals at ``x``, simulating it alone."""
    exp = problem.experiments[i]
    params = problem.parameters_for(x, i)
    traj = simulate_experiment(exp, fmus[exp.model], params, runner=runner)
    return ExperimentResult(exp, params, traj, experiment_fitness(exp, traj.time, traj.outputs))
