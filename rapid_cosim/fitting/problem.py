"""Experiments -> one problem: the search space the estimators explore and, per
experiment, which search dimension sets which FMU parameter.

Joint fits: a parameter estimated in several experiments is one search dimension and
must be declared identically everywhere (same bounds, label, scale, start); a
``per_experiment`` parameter becomes one dimension per experiment, named
``"<param>@<experiment>"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..data import close_matches
from ..errors import ConfigError
from ..experiment import EstimateSpec, Experiment, config_key
from .search import SearchSpace
from ..simulator import ParameterInfo
from ..simulator.fmu import OUTPUT_TYPES, REAL_TYPES
from ..simulator.rocof import FREQUENCY, ROCOF
from ..simulator.delayed import DELAYED_FREQUENCY

@dataclass(frozen=True, eq=False)
class Problem:
    """One or more experiments fitted together.

    ``space.names`` are FMU parameter names for shared parameters and
    ``"<param>@<experiment>"`` for per-experiment ones; ``labels`` follow the same order.
    ``assignments[i]`` pairs each estimated FMU parameter of experiment ``i`` with its
    index in a search vector.
    """

    experiments: tuple[Experiment, ...]
    space: SearchSpace
    labels: tuple[str, ...]
    x0: np.ndarray
    assignments: tuple[tuple[tuple[str, int], ...], ...]

    @property
    def names(self) -> tuple[str, ...]:
        return self.space.names

    def experiment_index(self, name: str) -> int:
        for i, e in enumerate(self.experiments):
            if e.name == name:
                return i
        raise KeyError(f"no experiment {name!r}; experiments: "
                       f"{', '.join(e.name for e in self.experiments)}")

    def parameters_for(self, x, i: int | str) -> dict[str, float]:
        """FMU parameter values (fixed and estimated) of experiment ``i`` at search point ``x``."""
        if isinstance(i, str):
            i = self.experiment_index(i)
        x = np.asarray(x, dtype=float)
        if x.shape != (self.space.dim,):
            raise ValueError(f"x has shape {x.shape}; the search space has {self.space.dim} "
                             f"dimensions ({', '.join(self.names)})")
        return assign_parameters(self.experiments[i], self.assignments[i], x)


def assign_parameters(experiment: Experiment, assignment: Sequence[tuple[str, int]], x) -> dict[str, float]:
    """The experiment's fixed values plus ``x[j]`` for each ``(name, j)`` of its assignment;
    unchecked, as workers call it once per simulation."""
    values = dict(experiment.fixed)
    values.update({name: float(x[j]) for name, j in assignment})
    return values


def check_parameters(experiment: Experiment, parameter_info: Mapping[str, ParameterInfo]) -> None:
    """Every name in ``[fixed]``/``[estimate]`` must exist in the model, and values and
    bounds must lie within the declared min/max. ``build_problem`` calls this; call it
    per experiment when experiments use different models."""
    file = str(experiment.config_path)
    known = list(parameter_info)
    checks = [(n, config_key("fixed", n), [v]) for n, v in experiment.fixed.items()]
    checks += [(s.name, config_key("estimate", s.name), [s.min, s.max]) for s in experiment.estimate]
    for name, key, values in checks:
        info = parameter_info.get(name)
        if info is None:
            close = close_matches(name, known, n=5)
            tail = name.rsplit(".", 1)[-1].lower()
            close += [k for k in known if k.rsplit(".", 1)[-1].lower() == tail and k not in close]
            hint = (f"; close matches: {', '.join(close)}" if close
                    else f"; no close match among the {len(known)} parameters of the model")
            raise ConfigError(f"model {experiment.model} has no parameter '{name}'{hint}", file, key)
        if key.startswith("estimate") and info.type not in ("Real", "Float64"):
            raise ConfigError(f"'{name}' is a{'n' if info.type[0] in 'AEIOU' else ''} {info.type} parameter of "
                              f"{experiment.model} (a flag: a choice of structure, not a value to fit): give it in "
                              "[fixed], and compare the choices as structures", file, key)
        if not info.settable:
            raise ConfigError(f"'{name}' of {experiment.model} cannot be set: it is calculated from other "
                              f"parameters, or a {info.type} parameter of an FMI 3.0 FMU (Float64 ones can be set)",
                              file, key)
        if info.type == "Integer" and any(v != round(v) for v in values):
            raise ConfigError(f"'{name}' is an Integer parameter of {experiment.model}: {values[0]:g} is not a "
                              "whole number", file, key)
        if info.type == "Boolean" and any(v not in (0.0, 1.0) for v in values):
            raise ConfigError(f"'{name}' is a Boolean parameter of {experiment.model}: give 0 or 1, not "
                              f"{values[0]:g}", file, key)
        lo = -math.inf if info.min is None else info.min
        hi = math.inf if info.max is None else info.max
        for v in values:
            if not lo <= v <= hi:
                raise ConfigError(f"{v:g} is outside the range the model declares for '{name}': "
                                  f"[{lo:g}, {hi:g}]", file, key)


def check_signals(experiment: Experiment, types: Mapping[str, str], model_inputs: Sequence[str]) -> None:
    """Every output compared is a variable the model can record (by its FMI type), every
    ``[inputs]`` entry one of its inputs (Real), and every input of the model driven."""
    file = str(experiment.config_path)
    recordable = (*OUTPUT_TYPES, "Enumeration")  # FMI 2.0 and 3.0 numeric types
    for out in experiment.outputs:
        key = config_key("data.outputs", out)
        if out not in types:
            close = close_matches(out, list(types), n=3)
            hint = f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""
            raise ConfigError(f"model {experiment.model} has no output '{out}'{hint}", file, key)
        if types[out] not in recordable:
            raise ConfigError(f"'{out}' is a {types[out]} variable; numeric ones (Real, Integer, Enumeration "
                              "and Boolean; in FMI 3.0 the Float and Int types) can be compared", file, key)
    listing = ", ".join(model_inputs) or "(none)"
    for spec in experiment.inputs:
        key = config_key("inputs", spec.name)
        if spec.name not in model_inputs:
            raise ConfigError(f"model {experiment.model} has no input '{spec.name}'; its inputs: {listing}",
                              file, key)
        if types[spec.name] not in REAL_TYPES:
            raise ConfigError(f"input '{spec.name}' is a {types[spec.name]} input; rapid-cosim drives Real "
                              "(FMI 3.0: Float64) inputs only", file, key)
    driven = {s.name for s in experiment.inputs}
    if FREQUENCY in driven:  # a recorded-frequency bench's ROCOF and delayed frequency derive from it
        driven |= {ROCOF, DELAYED_FREQUENCY}  # (simulator.rocof, simulator.delayed)
    undriven = [n for n in model_inputs if n not in driven]
    if undriven:
        raise ConfigError(f"model {experiment.model} has input(s) {', '.join(undriven)} that no [inputs] entry "
                          f"drives (e.g. {undriven[0]} = {{ column = \"...\" }})", file, "inputs")


def build_problem(experiments: Sequence[Experiment],
                  parameter_info: Mapping[str, ParameterInfo] | None = None) -> Problem:
    """Join experiments into one search problem (see the module docstring for the rules)."""
    experiments = tuple(experiments)
    if not experiments:
        raise ValueError("build_problem needs at least one experiment")
    seen: dict[str, Experiment] = {}
    for e in experiments:
        if e.name in seen:
            raise ConfigError(f"experiment name '{e.name}' is also used by "
                              f"{seen[e.name].config_path}; names must be unique in a joint fit",
                              str(e.config_path), "experiment.name")
        seen[e.name] = e
    if parameter_info is not None:
        for e in experiments:
            check_parameters(e, parameter_info)

    shared: dict[str, tuple[EstimateSpec, Experiment]] = {}
    for e in experiments:
        for s in e.estimate:
            if s.name not in shared:
                shared[s.name] = (s, e)
                continue
            first, where = shared[s.name]
            if first.per_experiment and s.per_experiment:
                continue
            diff = [f for f in ("per_experiment", "min", "max", "label", "scale", "start")
                    if getattr(first, f) != getattr(s, f)]
            if diff:
                shown = ", ".join(f"{f} = {getattr(s, f)!r} here but {getattr(first, f)!r} in "
                                  f"{where.config_path}" for f in diff)
                raise ConfigError(f"'{s.name}' is estimated by both {where.name} and {e.name} and "
                                  f"must be declared identically: {shown}",
                                  str(e.config_path), config_key("estimate", s.name))
    for name, (spec, where) in shared.items():
        if spec.per_experiment:
            continue
        for e in experiments:
            if all(s.name != name for s in e.estimate):
                how = "fixed" if name in e.fixed else "not estimated"
                raise ConfigError(f"'{name}' is estimated in {where.name} ({where.config_path}) "
                                  f"but {how} in {e.name}; a shared parameter is estimated in "
                                  f"every experiment of a joint fit (or set per_experiment = true)",
                                  str(e.config_path), config_key("estimate", name))

    names: list[str] = []
    labels: list[str] = []
    lower: list[float] = []
    upper: list[float] = []
    log: list[bool] = []
    x0: list[float] = []
    index: dict[str, int] = {}
    assignments = []
    for e in experiments:
        pairs = []
        for s in e.estimate:
            dim = f"{s.name}@{e.name}" if s.per_experiment else s.name
            if dim not in index:
                index[dim] = len(names)
                names.append(dim)
                labels.append(f"{s.label}@{e.name}" if s.per_experiment else s.label)
                lower.append(s.min)
                upper.append(s.max)
                log.append(s.scale == "log")
                midpoint = np.sqrt(s.min * s.max) if s.scale == "log" else 0.5 * (s.min + s.max)
                x0.append(s.start if s.start is not None else midpoint)
            pairs.append((s.name, index[dim]))
        assignments.append(tuple(pairs))
    if not names:
        raise ConfigError("nothing to estimate: no [estimate] entries in any experiment",
                          str(experiments[0].config_path), "estimate")
    return Problem(experiments, SearchSpace(tuple(names), np.array(lower), np.array(upper), tuple(log)),
                   tuple(labels), np.array(x0), tuple(assignments))


