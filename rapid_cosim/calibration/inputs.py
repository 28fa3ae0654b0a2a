"""The inputs of a run: its problem and its FMUs by content, from config files, from
experiments made in code, or from an archive alone."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from ..archive import RunArchive
from ..compiler.source import ModelSource
from ..data import MeasuredData
from ..data.timebase import Repairs
from ..errors import BuildError, ConfigError, FmuError
from ..experiment import Experiment, load_experiment, parse_experiment
from ..fitting.fitness import combination_weights, gaussian_log_likelihood
from ..fitting.problem import Problem, build_problem, check_parameters, check_signals
from ..fitting.search import Evaluations
from ..simulator import FmuRef, get_simulator


@dataclass(frozen=True)
class RunInputs:
    """A problem with its FMUs by content: everything an objective needs."""

    problem: Problem
    fmus: dict[str, FmuRef]

    @property
    def experiments(self) -> tuple[Experiment, ...]:
        return self.problem.experiments


def inputs_from_configs(paths: Sequence[str | Path], *, source: ModelSource = ModelSource()) -> RunInputs:
    """Experiments from config files; see :func:`inputs_from_experiments`."""
    if not paths:
        raise ConfigError("give at least one experiment config")
    return inputs_from_experiments([load_experiment(p) for p in paths], source=source)


def inputs_from_experiments(experiments: Sequence[Experiment], *, source: ModelSource = ModelSource(),
                            fmus: Mapping[str, FmuRef] | None = None) -> RunInputs:
    """A run's inputs from experiments in memory: their FMUs built from ``source`` if needed (or taken
    from ``fmus``, by model name) and checked against the experiments (unknown
    parameters, values outside the declared ranges)."""
    if not experiments:
        raise ConfigError("give at least one experiment")
    refs = dict(fmus or {})
    for exp in experiments:
        if exp.model not in refs:
            try:
                fmu = source.fmu(exp.model)
            except BuildError as e:  # a misspelt bench is the config's mistake: named by its key
                if not str(e).startswith("unknown model"):
                    raise
                key = "experiment.fmu" if exp.model.endswith(".fmu") else "experiment.model"
                raise ConfigError(str(e), str(exp.config_path), key) from None
            refs[exp.model] = FmuRef.from_path(fmu, exp.model)
    return RunInputs(_checked_problem(experiments, refs), {m: refs[m] for m in {e.model for e in experiments}})


def _checked_problem(experiments: Sequence[Experiment], fmus: Mapping[str, FmuRef]) -> Problem:
    sims = {}
    for model, ref in fmus.items():
        try:
            sims[model] = get_simulator(ref)
        except FmuError as e:  # the FMU is named by the config key that chose it, not its cached copy
            exp = next((x for x in experiments if x.model == model), None)
            if exp is None:
                raise
            reason = str(e).split(": ", 1)[-1]
            key = "experiment.fmu" if model.endswith(".fmu") else "experiment.model"
            raise ConfigError(f"{model}: {reason}", str(exp.config_path), key) from None
    for exp in experiments:
        sim = sims[exp.model]
        check_parameters(exp, {n: p for n, p in sim.parameters.items() if p.settable})
        check_signals(exp, sim.fmu.types, sim.fmu.inputs)
    return build_problem(experiments)


def inputs_from_archive(archive: RunArchive) -> RunInputs:
    """The run's problem and FMUs rebuilt from the archive alone (no file is read)."""
    configs, data, blobs, hashes = archive.configs, archive.data, archive.fmus, archive.hashes["fmus"]
    meta = archive.options.get("experiments", {})
    experiments = []
    def measured(key: str, time_column: str, repairs: dict | None) -> MeasuredData:
        columns = dict(data[key])
        made = MeasuredData.from_arrays(columns.pop(time_column), columns, source=f"{archive.path}:/inputs/data/{key}")
        if not repairs:
            return made
        said = Repairs(repairs["repeated"], repairs["reordered"], tuple(repairs["words"]))
        return MeasuredData(made.source, made.time, made.columns, made.valid, None, said)  # as loading did them

    for name, text in configs.items():
        info = meta.get(name, {})
        repairs = info.get("repairs", {})
        files = {file: measured(f"{name}|{file}", time, repairs.get(file)) for file, time in info.get("files", {}).items()}
        experiments.append(parse_experiment(text, info.get("config_path", f"{archive.path}:{name}"),
                                            data=measured(name, info.get("time_column", "time"), repairs.get("data")),
                                            files=files))
    fmus = {model: FmuRef(model, hashes[model], raw) for model, raw in blobs.items()}  # archive.fmus checked them
    return RunInputs(_checked_problem(experiments, fmus), fmus)


def log_likelihood_for(problem: Problem) -> Callable[[Evaluations], np.ndarray] | None:
    """Gaussian likelihood with each experiment's configured noise level, or None if an
    experiment has none (then the Bayesian method cannot run). Whitened experiments
    (``[noise]``) carry their likelihood in their value: ``-n/2`` times the mean squared
    whitened residual."""
    weights = combination_weights(problem.experiments)
    if weights is not None:
        return lambda ev: np.where(np.all(np.isfinite(ev.rssd), axis=1), -0.5 * (ev.rssd @ weights), -np.inf)
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
