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

import json
import warnings
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .. import __version__
from ..compiler import ensure_fmu
from ..data import MeasuredData
from ..errors import ArchiveError, ConfigError, RapidCosimError
from ..estimators import parse_method, run_chain
from ..estimators.base import Evaluations, EstimationResult, Iteration
from ..estimators.chain import REGISTRY
from ..evaluate import PENALTY, ProblemObjective
from ..experiment import Experiment, load_experiment, parse_experiment
from ..problem import Problem, build_problem, check_parameters
from ..fitness import gaussian_log_likelihood
from ..simulator import DEFAULT_RUNNER, FmuRef, get_simulator
from .store import ArchiveWriter, RunArchive, data_sha256


@dataclass(frozen=True)
class RunOptions:
    """How a run is made, beyond its configs: kept in the archive."""

    method: str = "pf:10+nm"
    seed: int = 1
    n_jobs: int = 1
    backend: str = "loky"
    penalty: float = PENALTY
    estimator_options: dict[str, dict[str, Any]] = field(default_factory=dict)  # {"pf": {"n_particles": 50}}
    runner: str = DEFAULT_RUNNER  # which simulator runner produced the run (see rapid_cosim.simulator)

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, data: Mapping) -> "RunOptions":
        known = {f.name for f in fields(cls)}
        values = {k: v for k, v in data.items() if k in known}
        values.setdefault("runner", "python")  # archives from before the compiled runner
        return cls(**values)


def parse_option_overrides(items: Sequence[str]) -> dict[str, dict[str, Any]]:
    """``["pf.n_particles=50", "nm.max_fev=200"]`` -> nested dict, checked against the
    methods' option classes so that a typo fails before any simulation."""
    out: dict[str, dict[str, Any]] = {}
    for item in items or []:
        key, sep, raw = item.partition("=")
        method, dot, name = key.strip().partition(".")
        if not sep or not dot:
            raise RapidCosimError(f"--option expects METHOD.NAME=VALUE (e.g. pf.n_particles=50), got {item!r}")
        if method not in REGISTRY:
            raise RapidCosimError(f"--option {key}: unknown method {method!r}; methods: {', '.join(REGISTRY)}")
        options_cls = REGISTRY[method][1]
        allowed = [f.name for f in fields(options_cls)]
        if name not in allowed:
            raise RapidCosimError(f"--option {key}: {method} has no option {name!r}; options: {', '.join(allowed)}")
        out.setdefault(method, {})[name] = _parse_value(raw.strip())
    return out


def _parse_value(raw: str):
    lowered = raw.lower()
    if lowered in ("none", "null"):
        return None
    if lowered in ("true", "false"):
        return lowered == "true"
    for kind in (int, float):
        try:
            return kind(raw)
        except ValueError:
            pass
    return raw


def _stage_options(options: RunOptions) -> dict:
    return {m: REGISTRY[m][1](**kw) for m, kw in options.estimator_options.items()}


# --------------------------------------------------------------------------- the run's inputs


@dataclass(frozen=True)
class RunInputs:
    """A problem with its FMUs by content: everything an objective needs."""

    problem: Problem
    fmus: dict[str, FmuRef]

    @property
    def experiments(self) -> tuple[Experiment, ...]:
        return self.problem.experiments


def inputs_from_configs(paths: Sequence[str | Path], *, package: str | Path = "modelica/iGrGen",
                        fmu_dir: str | Path = "fmus", compiler: str = "auto") -> RunInputs:
    """Experiments from config files; their FMUs built if needed and checked against the
    configs (unknown parameters, values outside the declared ranges)."""
    if not paths:
        raise ConfigError("give at least one experiment config")
    experiments = [load_experiment(p) for p in paths]
    fmus = {}
    for exp in experiments:
        if exp.model not in fmus:
            fmus[exp.model] = FmuRef.from_path(ensure_fmu(exp.model, package=package, fmu_dir=fmu_dir,
                                                          compiler=compiler), exp.model)
    return RunInputs(_checked_problem(experiments, fmus), fmus)


def _checked_problem(experiments: Sequence[Experiment], fmus: Mapping[str, FmuRef]) -> Problem:
    infos = {}
    for model, ref in fmus.items():
        sim = get_simulator(ref)
        infos[model] = {n: p for n, p in sim.parameters.items() if p.settable}
    for exp in experiments:
        check_parameters(exp, infos[exp.model])
    return build_problem(experiments)


def inputs_from_archive(archive: RunArchive) -> RunInputs:
    """The run's problem and FMUs rebuilt from the archive alone (no file is read)."""
    configs, data, blobs, hashes = archive.configs, archive.data, archive.fmus, archive.hashes["fmus"]
    meta = archive.options.get("experiments", {})
    experiments = []
    for name, text in configs.items():
        info = meta.get(name, {})
        columns = dict(data[name])
        time_column = info.get("time_column", "time")
        measured = MeasuredData.from_arrays(columns.pop(time_column), columns,
                                            source=f"{archive.path}:/inputs/data/{name}")
        experiments.append(parse_experiment(text, info.get("config_path", f"{archive.path}:{name}"), data=measured))
    fmus = {model: FmuRef(model, hashes[model], raw) for model, raw in blobs.items()}  # archive.fmus checked them
    return RunInputs(_checked_problem(experiments, fmus), fmus)


def log_likelihood_for(problem: Problem) -> Callable[[Evaluations], np.ndarray] | None:
    """Gaussian likelihood with each experiment's configured noise level, or None if an
    experiment has none (then the Bayesian method cannot run)."""
    sigma, counts = [], []
    for exp in problem.experiments:
        if not exp.noise_sigma:
            return None
        weighted = [o for o in exp.outputs if exp.weights[o] > 0]
        if len(weighted) != 1:
            raise ConfigError("the Bayesian fit needs exactly one output of positive weight per experiment",
                              str(exp.config_path), "data.outputs")
        out = weighted[0]
        sigma.append(exp.noise_sigma[out])
        counts.append(exp.windowed_data().n_valid(exp.outputs[out]))
    sigma_arr, counts_arr = np.array(sigma), np.array(counts, dtype=float)
    return lambda ev: gaussian_log_likelihood(ev.rssd, counts_arr, sigma_arr)


# --------------------------------------------------------------------------- replay plumbing


class _RecordingObjective:
    """Wraps the objective: remembers every row's per-experiment RSSD (the archive keeps
    them) and serves rows already known (replay) without simulating them."""

    def __init__(self, objective: ProblemObjective, known: Mapping[bytes, tuple[float, bool, np.ndarray]] | None = None):
        self.objective = objective
        self.known = dict(known or {})
        self.simulated = 0

    def __call__(self, X: np.ndarray) -> Evaluations:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        keys = [row.tobytes() for row in X]
        todo = [i for i, k in enumerate(keys) if k not in self.known]
        if todo:
            fresh = self.objective(X[todo])
            self.simulated += len(todo)
            for j, i in enumerate(todo):
                self.known[keys[i]] = (float(fresh.fitness[j]), bool(fresh.failed[j]), fresh.rssd[j].copy())
        rows = [self.known[k] for k in keys]
        return Evaluations(np.array([r[0] for r in rows]), np.vstack([r[2] for r in rows]),
                           np.array([r[1] for r in rows], dtype=bool))

    def rssd_of(self, X: np.ndarray) -> np.ndarray:
        return np.vstack([self.known[row.tobytes()][2] for row in np.atleast_2d(X)])


def _same_iteration(a: Iteration, b: Iteration) -> str | None:
    """Why two iterations differ (ignoring wall time), or None if they are identical."""
    checks = [("stage", a.stage == b.stage), ("index", a.index == b.index),
              ("particles", np.array_equal(a.x, b.x)), ("fitness", np.array_equal(a.fitness, b.fitness)),
              ("weights", np.array_equal(a.weights, b.weights)), ("failed", np.array_equal(a.failed, b.failed)),
              ("best", np.array_equal(a.best_x, b.best_x) and a.best_fitness == b.best_fitness),
              ("n_sims", a.n_sims == b.n_sims), ("rng state", a.rng_state == b.rng_state)]
    bad = [name for name, ok in checks if not ok]
    return ", ".join(bad) if bad else None


class _Progress:
    """A tqdm bar over iterations showing the best fitness and simulations so far."""

    def __init__(self, method: str, enabled: bool):
        self.bar = None
        if enabled:
            from tqdm.auto import tqdm

            total = sum(s.max_iter for s in parse_method(method) if s.max_iter) or None
            self.bar = tqdm(total=total, desc=method, unit="it", dynamic_ncols=True)

    def update(self, it: Iteration) -> None:
        if self.bar is not None:
            if self.bar.total is not None and self.bar.n >= self.bar.total:
                self.bar.total = None
            self.bar.set_postfix_str(f"{it.stage} best {it.best_fitness:.4g}, {it.n_sims} sims")
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _archive_options(options: RunOptions, inputs: RunInputs) -> dict:
    return {**options.to_json(), "rapid_cosim_version": __version__,
            "experiments": {e.name: {"config_path": str(e.config_path), "model": e.model,
                                     "time_column": e.time_column} for e in inputs.experiments}}


def _archived_data(exp: Experiment) -> dict[str, np.ndarray]:
    columns = {exp.time_column: np.asarray(exp.data.time, dtype=float)}
    columns.update({name: np.asarray(values, dtype=float) for name, values in exp.data.columns.items()})
    return columns


def _objective(inputs: RunInputs, options: RunOptions, known=None) -> _RecordingObjective:
    return _RecordingObjective(ProblemObjective(inputs.problem, inputs.fmus, n_jobs=options.n_jobs,
                                                backend=options.backend, penalty=options.penalty,
                                                runner=options.runner), known)


def _execute(inputs: RunInputs, options: RunOptions, objective: _RecordingObjective,
             on_iteration: Callable[[Iteration], None], progress: bool) -> EstimationResult:
    problem = inputs.problem
    log_likelihood = log_likelihood_for(problem)
    if any(s.name == "smc" for s in parse_method(options.method)) and log_likelihood is None:
        raise ConfigError("method smc needs a noise level in every experiment: set [fitness] noise")
    bar = _Progress(options.method, progress)

    def callback(it: Iteration) -> None:
        on_iteration(it)
        bar.update(it)

    try:
        return run_chain(objective, problem.space, options.method, options=_stage_options(options),
                         rng=np.random.default_rng(options.seed), callback=callback, x0=problem.x0,
                         log_likelihood=log_likelihood)
    finally:
        bar.close()


# --------------------------------------------------------------------------- entry points


def start_run(inputs: RunInputs, options: RunOptions, archive: str | Path, *, progress: bool = True) -> EstimationResult:
    """Estimate and archive every iteration as it completes."""
    try:  # a bad method string or option fails before the archive exists
        parse_method(options.method)
        _stage_options(options)
    except (ValueError, TypeError) as e:
        raise RapidCosimError(str(e)) from None
    problem = inputs.problem
    objective = _objective(inputs, options)
    Path(archive).parent.mkdir(parents=True, exist_ok=True)
    with ArchiveWriter.create(
            archive, method=options.method, seed=options.seed, names=problem.names,
            lower=problem.space.lower, upper=problem.space.upper,
            configs={e.name: e.config_text for e in problem.experiments},
            options=_archive_options(options, inputs),
            fmus={m: ref.content for m, ref in inputs.fmus.items()},
            data={e.name: _archived_data(e) for e in problem.experiments},
            n_experiments=len(problem.experiments)) as writer:
        result = _execute(inputs, options, objective, lambda it: writer.append(it, objective.rssd_of(it.x)), progress)
        writer.finish(result)
    return result


def resume_run(archive: str | Path, *, n_jobs: int | None = None, backend: str | None = None,
               progress: bool = True) -> EstimationResult:
    """Continue an interrupted run; the result equals that of an uninterrupted run."""
    with RunArchive(archive) as view:
        if view.status == "finished":
            raise ArchiveError(f"{archive}: the run is finished; use 'rapid-cosim rerun' to reproduce it")
        inputs = inputs_from_archive(view)
        options = _resumed_options(view, n_jobs, backend)
        stored = view.iterations()
        ev = view.evaluations()
    known = {x.tobytes(): (float(f), bool(fl), r.copy()) for x, f, fl, r in zip(ev.x, ev.fitness, ev.failed, ev.rssd)}
    objective = _objective(inputs, options, known)
    clock = {"offset": 0.0}
    with ArchiveWriter.reopen(archive) as writer:
        def on_iteration(it: Iteration) -> None:
            if it.index < len(stored):
                why = _same_iteration(it, stored[it.index])
                if why:
                    raise ArchiveError(f"{archive}: the replay differs from the archive at iteration {it.index} "
                                       f"({why}); was the archive written by another version?")
                clock["offset"] = stored[it.index].wall_time - it.wall_time
                return
            # wall time continues the interrupted run's clock
            writer.append(replace(it, wall_time=it.wall_time + clock["offset"]), objective.rssd_of(it.x))

        result = _execute(inputs, options, objective, on_iteration, progress)
        result = replace(result, wall_time=result.wall_time + clock["offset"])
        writer.finish(result)
    return result


def _resumed_options(view: RunArchive, n_jobs: int | None, backend: str | None) -> RunOptions:
    options = RunOptions.from_json(view.options)
    if options.method != view.method or options.seed != view.seed:
        raise ArchiveError(f"{view.path}: the stored options disagree with the run's method/seed")
    return replace(options, n_jobs=options.n_jobs if n_jobs is None else n_jobs,
                   backend=options.backend if backend is None else backend)


@dataclass(frozen=True)
class RerunReport:
    identical: bool
    iterations_compared: int
    first_difference: str | None
    result: EstimationResult
    simulations: int


def rerun(archive: str | Path, *, n_jobs: int | None = None, backend: str | None = None,
          progress: bool = True) -> RerunReport:
    """Execute the archived run again, every simulation included, and compare."""
    with RunArchive(archive) as view:
        inputs = inputs_from_archive(view)
        options = _resumed_options(view, n_jobs, backend)
        stored = view.iterations()
        archived = view.result()
    objective = _objective(inputs, options)
    differences: list[str] = []

    def on_iteration(it: Iteration) -> None:
        if it.index >= len(stored):
            differences.append(f"iteration {it.index} is not in the archive")
        else:
            why = _same_iteration(it, stored[it.index])
            if why:
                differences.append(f"iteration {it.index}: {why}")

    result = _execute(inputs, options, objective, on_iteration, progress)
    if archived is not None:
        if not (np.array_equal(result.x, archived.x) and result.fun == archived.fun and result.nfev == archived.nfev
                and result.nit == archived.nit):
            differences.append("final result")
    elif len(stored) != result.nit:
        differences.append(f"the archive holds {len(stored)} iterations of an unfinished run, the re-run made {result.nit}")
    return RerunReport(identical=not differences, iterations_compared=min(len(stored), result.nit),
                       first_difference=differences[0] if differences else None, result=result,
                       simulations=objective.simulated)


def summary_json(archive: str | Path) -> dict:
    """The archive's summary with the experiments it fitted (for ``show --json``)."""
    with RunArchive(archive) as view:
        out = view.summary()
        out["experiments"] = sorted(view.configs)
        out["options"] = {k: v for k, v in view.options.items() if k != "experiments"}
    return json.loads(json.dumps(out))


def ensure_run(inputs: RunInputs, options: RunOptions, archive: str | Path, *,
               progress: bool = True) -> tuple[EstimationResult, str]:
    """Make-like: reuse a finished archive of the same run, resume an interrupted one,
    start one otherwise. Returns the result and what was done ('archived', 'resumed',
    'new'). An archive of a *different* run (method, seed, options, configs or data
    changed) is never overwritten: that would lose a record; the error says what differs.
    """
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
        if view.hashes["data"] != {e.name: data_sha256(_archived_data(e)) for e in inputs.experiments}:
            differences.append("measured data")
        if differences:
            raise ArchiveError(f"{archive} holds a run with another {', '.join(differences)}; "
                               "remove it (or choose another archive) to run again")
        stale_fmu = view.hashes["fmus"] != {m: ref.sha256 for m, ref in inputs.fmus.items()}
        finished = view.status == "finished"
        result = view.result() if finished else None
    if stale_fmu:
        warnings.warn(f"{archive} was made with another build of the FMU; 'rapid-cosim rerun {archive}' "
                      "checks that the archived result still holds", stacklevel=2)
    if finished:
        return result, "archived"
    return resume_run(archive, n_jobs=options.n_jobs, backend=options.backend, progress=progress), "resumed"
