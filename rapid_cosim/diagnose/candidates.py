"""Calibrate one candidate model (base + effects) jointly over the tests, as any run.

A candidate's experiments are the user's experiments with the model swapped for the
candidate's bench and the effect's parameters added to ``[estimate]`` (or, for a fit
at an effect's material size, to ``[fixed]``). They are built in memory, reusing the
user's measurements; their configs are also written beside the archive for the record
(never read back), and each candidate is an ordinary archived run that ``rapid-cosim
show``, ``rerun`` and the reports understand.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..calibration import RunOptions, best_run, inputs_from_experiments
from ..compiler.source import ModelSource
from ..fitting.objective import ProblemObjective, evaluate_in_detail
from ..experiment import Experiment, parse_experiment, render_config
from ..noise import RecorderNoise
from ..simulator import FmuRef
from .catalogue import BASE, CATALOGUE, EFFECTS, bench_name, effect_parameters


@dataclass(frozen=True)
class CandidateSpec:
    """Base model plus ``effects``; ``held`` pins effect parameters (a material-size fit)."""

    effects: tuple[str, ...] = ()
    held: tuple[tuple[str, float], ...] = ()

    @property
    def label(self) -> str:
        name = "+".join(self.effects) or BASE
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
    whitened: np.ndarray | None = None  # by the recorder's noise model (NaN where masked)
    simulated: np.ndarray | None = None  # the model's output at the samples


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
    waterfall: np.ndarray | None = field(default=None, repr=False)  # each start's final fitness (multistart)
    ends: np.ndarray | None = field(default=None, repr=False)  # each start's end point (physical units)

    def next_basin(self, margin_bic: float = 2.0) -> tuple[float, dict[str, float]] | None:
        """(criterion above the best, parameters) of the best end point outside the best's
        margin: the runner-up basin of the multistart, or None."""
        if self.waterfall is None or self.ends is None:
            return None
        delta = self.n_samples * np.log(self.waterfall / np.min(self.waterfall))
        outside = np.flatnonzero(np.isfinite(delta) & (delta > margin_bic))
        if not outside.size:
            return None
        k = outside[np.argmin(delta[outside])]
        return float(delta[k]), dict(zip(self.inputs.problem.names, map(float, self.ends[k])))

    @property
    def n_samples(self) -> int:
        return sum(int(np.sum(np.isfinite(t.residual))) for t in self.tests.values())

    def reached_best(self, margin_bic: float = 2.0) -> int | None:
        """Starts of the multistart that ended within ``margin_bic`` of the best (None:
        not a multistart fit). The fitness is the deviance per sample, so a criterion
        difference ``D`` is a fitness ratio ``exp(D / N)``."""
        if self.waterfall is None:
            return None
        f = self.waterfall[np.isfinite(self.waterfall)]
        if not f.size:
            return 0
        return int(np.sum(f <= np.min(f) * math.exp(margin_bic / max(self.n_samples, 1))))


def candidate_config(exp: Experiment, spec: CandidateSpec, *, model: str | Mapping[str, str] | None = None,
                     noise: RecorderNoise | None = None) -> str:
    """The TOML of ``exp`` turned into a candidate's experiment, on the candidate's bench
    for the experiment's base (``model``: another class, or one per base bench, such as
    the calibrated model written from it).

    ``noise``, the recorder's noise model, goes into ``[noise]``: the candidate is then
    fitted by the whitened least squares its criterion judges it by.

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
    relative = {p.name for e in spec.effects if EFFECTS[e].relative for p in EFFECTS[e].parameters}
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
    if noise is not None:
        (output,) = [o for o in exp.outputs if exp.weights[o] > 0]
        sections["noise"] = {output: noise.to_config()}
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
                          model: str | Mapping[str, str] | None = None,
                          noise: Mapping[str, RecorderNoise] | None = None) -> list[Experiment]:
    """The experiments as the candidate's, in memory: each one's measurements reused
    (``noise``: the recorder's model per test name, for the whitened fitness)."""
    out = []
    for exp in experiments:
        text = candidate_config(exp, spec, model=model, noise=(noise or {}).get(exp.name))
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
                     model: str | Mapping[str, str] | None = None, source: ModelSource,
                     fmus: dict[str, FmuRef] | None = None, noise: Mapping[str, RecorderNoise] | None = None):
    """The candidate's run inputs, its configs recorded in ``folder``; ``fmus`` caches the
    FMUs by model across candidates (each is built or loaded once)."""
    exps = candidate_experiments(experiments, spec, polish_from, model=model, noise=noise)
    record_configs(folder, exps)
    inputs = inputs_from_experiments(exps, source=source, fmus=fmus)
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
                  options: RunOptions, start: Mapping[str, float] | None = None, source: ModelSource,
                  progress: bool = False, fmus: dict[str, FmuRef] | None = None,
                  searches: Sequence[str] = (), noise: Mapping[str, RecorderNoise] | None = None) -> CandidateFit:
    """Calibrate the candidate by ``options.method``, from ``start`` (the nested model's
    optimum with the effects switched off) where the method takes a start.

    The diagnosis's method is multistart least squares (``ms``): Levenberg-Marquardt
    from a Sobol design over the whole box plus the nested start, whose waterfall
    (every start's end) certifies the optimum or shows it uncertain. ``searches`` are
    further methods run beside it, the best kept (the earlier practice: PF10+NM with
    ``pso:10+nm+scan+nm``)."""
    start = dict(start or {})
    nested = start if spec.effects and start and all(p.name in start for p in effect_parameters(spec.effects)) \
        else None
    inputs = candidate_inputs(workdir / "candidates" / spec.slug, experiments, spec, polish_from=nested,
                              source=source, fmus=fmus, noise=noise)
    if "ms" in options.method:
        # the starts that reach the best are counted within the criterion's 2 (the fitness is
        # the deviance per sample); a pair starts from its first effect's fit, the new
        # effect's parameters moved over their own design
        n = sum(ix.size for e in inputs.experiments for _, ix, _ in e.scored.columns)
        ms = {"margin": 2.0 / n, **options.estimator_options.get("ms", {})}
        if nested is not None and len(spec.effects) > 1:
            ms["vary"] = [p.name for p in effect_parameters(spec.effects[-1:]) if p.name in inputs.problem.names]
        if spec.held and nested is not None:  # an effect held at a size: the nested model's problem, from its fit
            ms.setdefault("n_starts", inputs.problem.space.dim)
            ms.setdefault("screen", 0)
        options = replace(options, estimator_options={**options.estimator_options, "ms": ms})
    archive = workdir / "candidates" / f"{spec.slug}.h5"
    result, archive = best_run(inputs, options, archive, searches, progress=progress, replace_stale=True)
    waterfall = ends = None
    if result.history and "start_fun" in result.history[-1].extras:
        waterfall = np.asarray(result.history[-1].extras["start_fun"], dtype=float)
        space = inputs.problem.space
        ends = space.clip(space.from_unit(np.asarray(result.history[-1].extras["start_u"], dtype=float)))
    return CandidateFit(spec, archive, inputs.experiments[0].model, result.best(),
                        n_estimated=len(result.names), fitness=float(result.fun), nfev=result.nfev,
                        tests=residuals_at(inputs, result.x), inputs=inputs, waterfall=waterfall, ends=ends)


def jacobian_at(inputs, x, step: float = 1e-3) -> dict[str, np.ndarray]:
    """Per experiment, the Jacobian (valid samples x parameters) of its residual vector
    as the objective scores it (whitened for whitened experiments), by forward
    differences of ``step`` in unit coordinates (backward at an upper bound), all in one
    batch. What the adequacy null takes out as the fit's share of the noise."""
    problem = inputs.problem
    space = problem.space
    X, steps = space.stepped(np.clip(space.to_unit(np.asarray(x, dtype=float)), 0.0, 1.0), step)
    _, R = ProblemObjective(problem, inputs.fmus).residuals(X)
    J = (R[1:] - R[0]).T / steps  # (samples, parameters), on the objective's uniform scale
    return {e.name: J[block] for e, block in experiment_blocks(problem)}


def experiment_blocks(problem) -> list[tuple]:
    """(experiment, slice) of each experiment's samples in the objective's residual
    vector (:meth:`~rapid_cosim.fitting.objective.ProblemObjective.residuals`)."""
    sizes = [sum(ix.size for _, ix, _ in e.scored.columns) for e in problem.experiments]
    edges = np.cumsum([0, *sizes])
    return [(e, slice(int(a), int(b))) for e, a, b in zip(problem.experiments, edges[:-1], edges[1:])]


def residuals_at(inputs, x) -> dict[str, ExperimentResiduals]:
    out = {}
    for r in evaluate_in_detail(inputs.problem, inputs.fmus, np.asarray(x)):
        (column,) = r.fit.residuals  # one output per staged test
        out[r.experiment.name] = ExperimentResiduals(
            r.experiment.name, r.fit.time, r.fit.residuals[column], r.fit.rssd, r.fit.offsets[column],
            r.fit.n_valid[column], r.fit.whitened.get(column), np.asarray(r.trajectory[column], dtype=float))
    return out


__all__ = ["CATALOGUE", "CandidateFit", "CandidateSpec", "ExperimentResiduals", "candidate_config",
           "candidate_experiments", "candidate_inputs", "default_start", "fit_candidate", "jacobian_at",
           "record_configs", "residuals_at", "experiment_blocks"]
