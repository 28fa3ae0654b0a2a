"""Runs that live in archives: start one, resume one, re-run one from the file alone.

Estimators are deterministic given their seed and the objective's values, so a run is
resumed by *replay*: it is executed again from the start with the archived evaluations
served from a cache (keyed by the exact bytes of each parameter vector). Replayed
iterations are checked against the archive and only new ones are appended, so a resumed
run ends exactly where the uninterrupted one would, for every method, without any
method having to serialise its internal state. A re-run is the same replay with the
cache left empty: every simulation is done again and every iteration compared.
"""

from __future__ import annotations

import contextlib
import json
import warnings
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from ..version import __version__
from ..archive import ArchiveWriter, RunArchive, RunStatus, data_sha256
from ..errors import ArchiveDamaged, ArchiveError, ConfigError, EngineLost, RunInterrupted
from ..estimators import parse_method, run_chain
from ..estimators.base import EstimationResult, Iteration
from ..experiment import Experiment
from ..fitting.engine import EngineSpec
from ..progress import Stage
from ..fitting.objective import ProblemObjective
from ..simulator import get_simulator
from .inputs import RunInputs, inputs_from_archive, log_likelihood_for
from .options import RunOptions, stage_options
from .replay import RecordingObjective, same_iteration


class _Progress:
    """One :class:`~rapid_cosim.progress.Stage` per estimator stage, showing the best
    fitness and simulations so far: bounded by the stage's cap where the method states one
    (``pf:10``), else counted (Nelder-Mead stops when it converges, far below its
    ``max_iter``); a bar on a terminal, plain lines in a log."""

    def __init__(self, options: RunOptions, enabled: bool):
        self.enabled, self.stage, self.name = enabled, None, None
        self.caps = {s.name: s.max_iter for s in parse_method(options.method)} if enabled else {}

    def update(self, it: Iteration) -> None:
        if not self.enabled:
            return
        if it.stage != self.name:
            self.close()
            self.name = it.stage
            self.stage = Stage(it.stage, self.caps.get(it.stage), unit="it")
        self.stage.update(1, f"best {it.best_fitness:.4g}, {it.n_sims} sims")

    def finish(self) -> None:
        self.close()

    def close(self) -> None:
        if self.stage is not None:
            self.stage.close()
            self.stage = None


def _simulation_paths(inputs: RunInputs, options: RunOptions) -> dict[str, str]:
    """Per model, what simulates it: the FMU's kind and the driver ("FMI 3.0 Co-Simulation,
    C driver"), as archives record it."""
    return {model: get_simulator(ref).run_path(options.runner) for model, ref in inputs.fmus.items()}


def _archive_options(options: RunOptions, inputs: RunInputs) -> dict:
    return {**options.to_json(), "rapid_cosim_version": __version__,
            "simulation_paths": _simulation_paths(inputs, options),
            "experiments": {e.name: {"config_path": str(e.config_path), "model": e.model,
                                     "time_column": e.time_column,
                                     "files": {s.file: s.time for s in e.inputs if s.file is not None},
                                     "repairs": {key: asdict(data.repairs) for key, data in
                                                 (("data", e.data), *e.files.items()) if data.repairs},
                                     "recording": e.recording.summary()}
                            for e in inputs.experiments}}


def _archived_data(exp: Experiment) -> dict[str, dict[str, np.ndarray]]:
    """The experiment's measurements as the archive keeps them: its data file under its
    name, each other file its inputs read under ``<name>|<file>``."""
    def columns(data, time_column):
        out = {time_column: np.asarray(data.time, dtype=float)}
        out.update({name: np.asarray(values, dtype=float) for name, values in data.columns.items()})
        return out

    stored = {exp.name: columns(exp.data, exp.time_column)}
    for spec in exp.inputs:
        if spec.file is not None:
            stored[f"{exp.name}|{spec.file}"] = columns(exp.files[spec.file], spec.time)
    return stored


def _all_data(experiments) -> dict[str, dict[str, np.ndarray]]:
    return {key: cols for e in experiments for key, cols in _archived_data(e).items()}


def _objective(inputs: RunInputs, options: RunOptions, known=None) -> RecordingObjective:
    return RecordingObjective(ProblemObjective(inputs.problem, inputs.fmus, engine=options.engine.make(),
                                               penalty=options.penalty, runner=options.runner), known)


def _execute(inputs: RunInputs, options: RunOptions, objective: RecordingObjective,
             on_iteration: Callable[[Iteration], None], progress: bool) -> EstimationResult:
    problem = inputs.problem
    log_likelihood = log_likelihood_for(problem)
    if any(s.name == "smc" for s in parse_method(options.method)) and log_likelihood is None:
        raise ConfigError("method smc needs a noise level in every experiment: set [fitness] noise")
    bar = _Progress(options, progress)
    events = getattr(objective.objective.engine, "events", [])
    seen = len(events)

    def callback(it: Iteration) -> None:
        nonlocal seen
        if len(events) > seen:  # what the engine went through (a lost worker) goes with the iteration
            it = replace(it, extras={**it.extras, "engine_events": np.array(events[seen:])})
            seen = len(events)
        on_iteration(it)
        bar.update(it)

    try:
        result = run_chain(objective, problem.space, options.method, options=stage_options(options),
                           rng=np.random.default_rng(options.seed), callback=callback, x0=problem.x0,
                           log_likelihood=log_likelihood)
        bar.finish()
        return result
    finally:
        bar.close()


# --------------------------------------------------------------------------- entry points


def start_run(inputs: RunInputs, options: RunOptions, archive: str | Path, *, progress: bool = True) -> EstimationResult:
    """Estimate and archive every iteration as it completes."""
    options.check()  # a bad method string or option fails before the archive exists
    problem = inputs.problem
    objective = _objective(inputs, options)
    Path(archive).parent.mkdir(parents=True, exist_ok=True)
    with ArchiveWriter.create(
            archive, method=options.method, seed=options.seed, names=problem.names,
            lower=problem.space.lower, upper=problem.space.upper,
            configs={e.name: e.config_text for e in problem.experiments},
            options=_archive_options(options, inputs),
            fmus={m: ref.content for m, ref in inputs.fmus.items()},
            data=_all_data(problem.experiments),
            n_experiments=len(problem.experiments)) as writer, _interruptible(writer):
        result = _execute(inputs, options, objective, lambda it: writer.append(it, objective.rssd_of(it.x)), progress)
        result = replace(result, failure_messages=tuple(objective.objective.failures.messages))
        writer.finish(result)
    return result


@contextlib.contextmanager
def _interruptible(writer: ArchiveWriter):
    """Ctrl-C (or SIGTERM, which the command line turns into it) ends the run with a
    :class:`RunInterrupted` that says how to resume; the writer then commits what it
    has and closes the archive as 'interrupted'."""
    try:
        yield
    except KeyboardInterrupt:
        raise RunInterrupted(writer.path, writer.n_iterations) from None
    except EngineLost as e:
        raise EngineLost(f"{e}; {writer.path} holds {writer.n_iterations} complete iterations: "
                         f"'rapid-cosim resume {writer.path} --joblib-backend loky' finishes the run on this "
                         "machine") from None


def resume_run(archive: str | Path, *, engine: Resumed = None, progress: bool = True) -> EstimationResult:
    """Continue an interrupted run, on the archived engine or ``engine``; the result
    equals that of an uninterrupted run."""
    with RunArchive(archive) as view:
        if view.status is RunStatus.FINISHED:
            raise ArchiveError(f"{archive}: the run is finished; use 'rapid-cosim rerun' to reproduce it")
        inputs = inputs_from_archive(view)
        options = _resumed_options(view, engine)
        stored, damage = view.intact_iterations()
        ev = view.evaluations(sum(len(it.x) for it in stored))
    if damage is not None:
        warnings.warn(f"{damage.path}: iteration {len(stored)} onwards is damaged ({damage.reason}); resuming from "
                      f"the {len(stored)} intact iterations, the rest is computed again", stacklevel=2)
    known = {x.tobytes(): (float(f), bool(fl), r.copy()) for x, f, fl, r in zip(ev.x, ev.fitness, ev.failed, ev.rssd)}
    objective = _objective(inputs, options, known)
    clock = {"offset": 0.0}
    with ArchiveWriter.reopen(archive, keep=len(stored)) as writer, _interruptible(writer):
        def on_iteration(it: Iteration) -> None:
            if it.index < len(stored):
                why = same_iteration(it, stored[it.index])
                if why:
                    raise ArchiveError(f"{archive}: the replay differs from the archive at iteration {it.index} "
                                       f"({why}); was the archive written by another version?")
                clock["offset"] = stored[it.index].wall_time - it.wall_time
                return
            # wall time continues the interrupted run's clock
            writer.append(replace(it, wall_time=it.wall_time + clock["offset"]), objective.rssd_of(it.x))

        result = _execute(inputs, options, objective, on_iteration, progress)
        # the failures kept are those this process simulated (replayed ones are not run again)
        result = replace(result, wall_time=result.wall_time + clock["offset"],
                         failure_messages=tuple(objective.objective.failures.messages))
        writer.finish(result)
    return result


# Where a resumed or re-run run goes: the archived engine (None), another one, or the
# archived one changed (a function of it: the CLI's settings, each over the archived one).
Resumed = EngineSpec | Callable[[EngineSpec], EngineSpec] | None


def _resumed_options(view: RunArchive, engine: Resumed) -> RunOptions:
    """The archived options, on the engine ``engine`` says: where a run goes on does not
    change its result."""
    options = RunOptions.from_json(view.options)
    if options.method != view.method or options.seed != view.seed:
        raise ArchiveError(f"{view.path}: the stored options disagree with the run's method/seed")
    if callable(engine):
        engine = engine(options.engine)
    return (options if engine is None else replace(options, engine=engine)).check()


@dataclass(frozen=True)
class RerunReport:
    identical: bool
    iterations_compared: int
    first_difference: str | None
    result: EstimationResult
    simulations: int
    finished: bool = True  # False: the archive held an unfinished run, compared as far as it went


def rerun(archive: str | Path, *, engine: Resumed = None, progress: bool = True) -> RerunReport:
    """Execute the archived run again, every simulation included, and compare."""
    with RunArchive(archive) as view:
        inputs = inputs_from_archive(view)
        options = _resumed_options(view, engine)
        stored = view.iterations()
        archived = view.result()
        recorded = view.options.get("simulation_paths")
    objective = _objective(inputs, options)
    differences: list[str] = []
    if recorded and recorded != _simulation_paths(inputs, options):
        differences.append(f"simulation path: archived {recorded}, now {_simulation_paths(inputs, options)}")

    def on_iteration(it: Iteration) -> None:
        if it.index >= len(stored):
            if archived is not None:  # an unfinished archive stops early; a finished one must not
                differences.append(f"iteration {it.index} is not in the archive")
        else:
            why = same_iteration(it, stored[it.index])
            if why:
                differences.append(f"iteration {it.index}: {why}")

    result = _execute(inputs, options, objective, on_iteration, progress)
    if archived is not None:
        if not (np.array_equal(result.x, archived.x) and result.fun == archived.fun and result.nfev == archived.nfev
                and result.nit == archived.nit):
            differences.append("final result")
        elif archived.failure_messages and archived.failure_messages != tuple(objective.objective.failures.messages):
            differences.append("the failed simulations' messages")
    elif len(stored) > result.nit:
        differences.append(f"the archive holds {len(stored)} iterations, the re-run made only {result.nit}")
    return RerunReport(identical=not differences, iterations_compared=min(len(stored), result.nit),
                       first_difference=differences[0] if differences else None, result=result,
                       simulations=objective.simulated, finished=archived is not None)


def summary_json(archive: str | Path) -> dict:
    """The archive's summary with the experiments it fitted (for ``show --json``)."""
    with RunArchive(archive) as view:
        out = view.summary()
        try:
            out["experiments"] = sorted(view.configs)
        except ArchiveDamaged as e:
            out["experiments"], out["damaged"] = ["(damaged)"], out["damaged"] + [str(e)]
        try:
            out["recordings"] = {name: info.get("recording") for name, info in
                                 view.options.get("experiments", {}).items() if info.get("recording")}
            out["options"] = {k: v for k, v in view.options.items() if k != "experiments"}
        except ArchiveDamaged as e:
            out["options"], out["damaged"] = None, out["damaged"] + [str(e)]
    return json.loads(json.dumps(out))


def ensure_run(inputs: RunInputs, options: RunOptions, archive: str | Path, *,
               progress: bool = True, replace_stale: bool = False) -> tuple[EstimationResult, str]:
    """Make-like: reuse a finished archive of the same run, resume an interrupted one,
    start one otherwise. Returns the result and what was done ('archived', 'resumed',
    'new', 'remade'). An archive of a *different* run (method, seed, options, configs or
    data changed) is not overwritten, since that would lose a record: the error says what
    differs. Workflows that own their work folder (a diagnosis's candidates, a
    structure selection) pass ``replace_stale``: their archive of another run is then
    made again, as a re-run after the data or the noise model changed must."""
    archive = Path(archive)
    if not archive.exists():
        return start_run(inputs, options, archive, progress=progress), "new"
    with RunArchive(archive) as view:
        stored = RunOptions.from_json(view.options)
        differences = []
        if (stored.method, stored.seed, stored.estimator_options, stored.penalty) != \
                (options.method, options.seed, options.estimator_options, options.penalty):
            differences.append("method, seed or estimator options")
        if view.configs != {e.name: e.config_text for e in inputs.experiments}:
            differences.append("experiment config")
        if view.hashes["data"] != {k: data_sha256(c) for k, c in _all_data(inputs.experiments).items()}:
            differences.append("measured data")
        if differences and not replace_stale:
            raise ArchiveError(f"{archive} holds a run with another {', '.join(differences)}; "
                               "remove it (or choose another archive) to run again")
        if not differences:
            stale_fmu = view.hashes["fmus"] != {m: ref.sha256 for m, ref in inputs.fmus.items()}
            finished = view.status is RunStatus.FINISHED
            result = view.result() if finished else None
    if differences:  # replace_stale: the workflow's own archive of another run, closed now
        archive.unlink()
        return start_run(inputs, options, archive, progress=progress), "remade"
    if stale_fmu:
        warnings.warn(f"{archive} was made with another build of the FMU; 'rapid-cosim rerun {archive}' "
                      "checks that the archived result still holds", stacklevel=2)
    if finished:
        return result, "archived"
    # the archived scheduler, with this run's workers and backend
    return resume_run(archive, engine=lambda archived: archived.overridden(options.engine.n_jobs,
                                                                           options.engine.backend),
                      progress=progress), "resumed"


# Searches run besides a run's own method when results are compared (structures,
# candidate effects), the best kept: a model must not lose for its search's failure. A
# swarm explores differently from a particle filter (in the structure study a PF chain
# collapsed onto a wrong mode of GGOV1's surface, integral gain 0.27 against 5, where a
# PSO chain found the plant's), and the scan stage finds limits that act only in a
# narrow valley of their range (see rapid_cosim.estimators.scan).
SEARCHES = ("pso:10+nm+scan+nm",)


def best_run(inputs: RunInputs, options: RunOptions, archive: str | Path, searches=SEARCHES, *,
             progress: bool = False, replace_stale: bool = False) -> tuple[EstimationResult, Path]:
    """The best of ``options.method`` (in ``archive``) and each of ``searches`` (in
    ``<archive stem>.<search>.h5``), every one an archived run; returns the best result
    and its archive."""
    archive = Path(archive)
    runs = []
    for method in dict.fromkeys([options.method, *searches]):
        path = archive if method == options.method else \
            archive.with_name(f"{archive.stem}.{method.replace(':', '').replace('+', '-')}.h5")
        result, _ = ensure_run(inputs, replace(options, method=method), path, progress=progress,
                               replace_stale=replace_stale)
        runs.append((float(result.fun), result, path))
    _, result, path = min(runs, key=lambda r: r[0])
    return result, path
