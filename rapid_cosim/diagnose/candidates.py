"""Calibrate one candidate model (base + effects) jointly over the tests, as any run.

A candidate's experiments are the user's experiments with the model swapped for the
candidate's bench and the effect's parameters added to ``[estimate]`` (or, for a fit
at an effect's material size, to ``[fixed]``). They are built in memory, reusing the
user's measurements; their configs are also written beside the archive for the record
(never read back), and each candidate is an ordinary archived run that ``rapid-cosim
show``, ``rerun`` and the reports understand.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..calibration import SEARCHES, RunOptions, best_run, ensure_run, inputs_from_experiments
from ..objective import ProblemObjective, evaluate_in_detail
from ..experiment import Experiment, parse_experiment, render_config
from ..simulator import FmuRef
from .catalogue import CATALOGUE, NONE, bench_name, effect_parameters


@dataclass(frozen=True)
class CandidateSpec:
    """Base model plus ``effects``; ``held`` pins effect parameters (a material-size fit)."""

    effects: tuple[str, ...] = ()
    held: tuple[tuple[str, float], ...] = ()

    @property
    def label(self) -> str:
        name = "+".join(self.effects) or NONE
        return name + "".join(f"@{k}={v:g}" for k, v in self.held)

    @property
    def slug(self) -> str:
        return self.label.replace("+", "_and_").replace("@", "_at_").replace("=", "-")


@dataclass(frozen=True)
class ExperimentResiduals:
    """Residuals of one test at a candidate's calibrated parameters."""

    name: str
    time: np.ndarray
    residual: np.ndarray  # NaN where masked
    rssd: float
    offset: float
    n_valid: int


@dataclass(frozen=True)
class CandidateFit:
    spec: CandidateSpec
    archive: Path
    model: str
    parameters: dict[str, float]  # estimated, FMU names
    n_estimated: int  # global parameters estimated (offsets are counted by the criterion)
    fitness: float
    nfev: int
    tests: dict[str, ExperimentResiduals] = field(default_factory=dict)
    inputs: object = field(default=None, repr=False)  # the RunInputs it was fitted on


def candidate_config(exp: Experiment, spec: CandidateSpec, *, model: str | Mapping[str, str] | None = None) -> str:
    """The TOML of ``exp`` turned into a candidate's experiment, on the candidate's bench
    for the experiment's base (``model``: another class, or one per base bench, such as
    the calibrated model written from it).

    The governor keeps the experiment's own bounds. The base model's optimum is neither
    a starting point (a particle at the base optimum with the effect
    off becomes the elite of the first iterations and holds the search in the basin
    where the effect does nothing: a rate limit's basin was missed in a third of the
    runs with it, in none of eight without) nor a centre for narrower bounds: an effect
    can move the base model's optimum far, to a bound even (an output limit 0.02 pu
    above the dispatch drove R from 0.049 to 0.12; a load controller drove Ts from 1.75
    s to 0.1 s), and bounds of a factor 4 around it left the plant's values outside.
    """
    raw = tomllib.loads(exp.config_text)
    data = dict(raw["data"])
    data_file = Path(data["file"])
    if not data_file.is_absolute():
        data_file = (Path(exp.config_path).parent / data_file).resolve()
    data["file"] = str(data_file)
    estimate = {k: dict(v) for k, v in raw.get("estimate", {}).items()}
    held = dict(spec.held)
    fixed = dict(raw.get("fixed", {}))
    relative = {p.name for e in spec.effects if CATALOGUE[e].relative for p in CATALOGUE[e].parameters}
    for p in effect_parameters(spec.effects):
        doc = 1.0
        if p.name in relative:  # a documented constant, freed around its documented value
            if p.name not in fixed:
                raise ValueError(f"{exp.name}: {p.name} is not documented in [fixed]; it cannot be freed")
            doc = float(fixed.pop(p.name))
        if p.name in held:
            fixed[p.name] = held[p.name] * doc
        else:
            estimate[p.name] = {"min": p.min * doc, "max": p.max * doc, "label": p.label, "scale": p.scale}
    if isinstance(model, Mapping):
        model = model.get(exp.model)
    sections = {**raw, "experiment": {**raw["experiment"], "model": model or bench_name(spec.effects, exp.model),
                                      "description": f"{raw['experiment'].get('description', exp.name)} "
                                                     f"[candidate {spec.label}]"},
                "data": data, "fixed": fixed, "estimate": estimate}
    return render_config(sections)


def default_start(spec: CandidateSpec, base: Mapping[str, float] | None) -> dict[str, float]:
    """The base model's optimum with the effects switched off: the nested point a
    candidate must do at least as well as (:func:`fit_candidate` polishes from there
    when its searches end worse)."""
    start = dict(base or {})
    for p in effect_parameters(spec.effects):
        start.setdefault(p.name, p.off)
    return start


def candidate_experiments(experiments: Sequence[Experiment], spec: CandidateSpec,
                          polish_from: Mapping[str, float] | None = None, *,
                          model: str | Mapping[str, str] | None = None) -> list[Experiment]:
    """The experiments as the candidate's, in memory: each one's measurements reused."""
    out = []
    for exp in experiments:
        text = candidate_config(exp, spec, model=model)
        if polish_from is not None:
            text = _with_start(text, polish_from)
        out.append(parse_experiment(text, exp.config_path, data=exp.data, files=exp.files))
    return out


def record_configs(folder: Path, experiments: Sequence[Experiment]) -> list[Path]:
    """``folder/<test>/config.toml`` of each experiment, for the record."""
    paths = []
    for exp in experiments:
        path = folder / exp.name / "config.toml"
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists() or path.read_text() != exp.config_text:
            path.write_text(exp.config_text)
        paths.append(path)
    return paths


def candidate_inputs(folder: Path, experiments: Sequence[Experiment], spec: CandidateSpec,
                     polish_from: Mapping[str, float] | None = None, *,
                     model: str | Mapping[str, str] | None = None, package, fmu_dir,
                     fmus: dict[str, FmuRef] | None = None):
    """The candidate's run inputs, its configs recorded in ``folder``; ``fmus`` caches the
    FMUs by model across candidates (each is built or loaded once)."""
    exps = candidate_experiments(experiments, spec, polish_from, model=model)
    record_configs(folder, exps)
    inputs = inputs_from_experiments(exps, package=package, fmu_dir=fmu_dir, fmus=fmus)
    if fmus is not None:
        fmus.update(inputs.fmus)
    return inputs


def _with_start(text: str, start: Mapping[str, float]) -> str:
    raw = tomllib.loads(text)
    for name, spec in raw.get("estimate", {}).items():
        if name in start:
            spec["start"] = float(min(max(start[name], spec["min"]), spec["max"]))
    return render_config(raw)


def fit_candidate(spec: CandidateSpec, experiments: Sequence[Experiment], workdir: Path, *,
                  options: RunOptions, start: Mapping[str, float] | None = None, package: str | Path,
                  fmu_dir: str | Path, progress: bool = False, fmus: dict[str, FmuRef] | None = None,
                  searches: Sequence[str] = SEARCHES) -> CandidateFit:
    """Calibrate the candidate by ``options.method`` and each of ``searches``, the best
    kept (a candidate must not lose for its search's failure: an output limit, like a
    load limit, acts only in a narrow valley of its range). If that ends worse than the
    point where its effects are switched off at ``start`` (the base optimum), which it
    nests, it missed that basin: Nelder-Mead polishes from there, also archived, and the
    better of the two stands."""
    start = dict(start or {})
    inputs = candidate_inputs(workdir / "candidates" / spec.slug, experiments, spec, package=package,
                              fmu_dir=fmu_dir, fmus=fmus)
    archive = workdir / "candidates" / f"{spec.slug}.h5"
    result, archive = best_run(inputs, options, archive, searches, progress=progress)
    if spec.effects and all(n in start for n in inputs.problem.names):
        nested = inputs.problem.space.clip(np.array([start[n] for n in inputs.problem.names]))
        if ProblemObjective(inputs.problem, inputs.fmus)(nested[None]).fitness[0] < result.fun:
            polish = f"{spec.slug}-from-base"
            polished_inputs = candidate_inputs(workdir / "candidates" / polish, experiments, spec,
                                               polish_from=start, package=package, fmu_dir=fmu_dir, fmus=fmus)
            polished, _ = ensure_run(polished_inputs, replace(options, method="nm"),
                                     workdir / "candidates" / f"{polish}.h5", progress=progress)
            if polished.fun < result.fun:
                inputs, result, archive = polished_inputs, polished, workdir / "candidates" / f"{polish}.h5"
    return CandidateFit(spec, archive, inputs.experiments[0].model, result.best(),
                        n_estimated=len(result.names), fitness=float(result.fun), nfev=result.nfev,
                        tests=residuals_at(inputs, result.x), inputs=inputs)


def residuals_at(inputs, x) -> dict[str, ExperimentResiduals]:
    out = {}
    for r in evaluate_in_detail(inputs.problem, inputs.fmus, np.asarray(x)):
        (column,) = r.fit.residuals  # one output per staged test
        out[r.experiment.name] = ExperimentResiduals(r.experiment.name, r.fit.time, r.fit.residuals[column], r.fit.rssd,
                                         r.fit.offsets[column], r.fit.n_valid[column])
    return out


__all__ = ["CATALOGUE", "CandidateFit", "CandidateSpec", "ExperimentResiduals", "candidate_config",
           "candidate_experiments", "candidate_inputs", "default_start", "fit_candidate", "record_configs",
           "residuals_at"]
