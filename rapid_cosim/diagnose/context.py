"""What one diagnosis works with: its options, the campaign's noise (fitted once), and
the candidate fits made so far, each fitted, predicted and judged once.

Candidates are built from a copy of the package (combinations of effects are generated
there; the user's package changes only if the verdict is written), with the recorder's
noise model in their configs, so that every fit is the whitened least squares its
criterion and adequacy judge it by.
"""

from __future__ import annotations

import re
import shutil
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..calibration import RunOptions
from ..compiler.source import ModelSource
from ..fitting.engine import EngineSpec, WholeFits, fit_here, map_fits
from ..errors import ConfigError, RapidCosimError
from ..data import close_matches
from ..experiment import Experiment
from ..simulator import DEFAULT_RUNNER
from .adequacy import Adequacy
from .candidates import CandidateFit, CandidateSpec, candidate_inputs, default_start, fit_candidate, \
    residuals_at
from .catalogue import BASE, BASES, CATALOGUE, bench_name, is_generated, write_bench
from .judging import Judge, jacobians_at
from .null import REPLICATES, KeptReplicates
from .selection import THRESHOLD, bic

# Multistart least squares from a Sobol design (rapid_cosim.estimators.multistart): the
# waterfall certifies each candidate's optimum. It replaced PF10+NM with a second search
# (pso:10+nm+scan+nm) on every candidate: on the field tests' rate-limit candidate it
# reaches the same optimum from 10 of 22 starts in 1400 simulations, and shows the two
# other basins (18.7 and 47 above it in BIC) and the plateau where the limits do not bind.
METHOD = "ms"


@dataclass(frozen=True)
class DiagnoseOptions:
    method: str = METHOD
    estimator_options: dict = field(default_factory=dict)
    seed: int = 1
    engine: EngineSpec = EngineSpec()  # where the work goes (dask: the objective's batches on the cluster)
    searches: tuple[str, ...] = ()  # run besides ``method`` on every candidate, the best kept
    threshold: float = THRESHOLD
    max_effects: int = 2
    candidates: tuple[str, ...] = tuple(CATALOGUE)
    write_model: bool = True  # write the named model into the package and re-calibrate with it
    model_name: str | None = None  # class name of the model written; default from the effects
    replicates: int = REPLICATES  # of the adequacy null's bootstrap
    judge: tuple[str, ...] = ()  # candidate labels whose adequacy is reported too (e.g. a study's truth)
    runner: str = DEFAULT_RUNNER  # the simulator runner of every fit (see rapid_cosim.simulator)

    def __post_init__(self):
        wrong = [c for c in self.candidates if c not in CATALOGUE]
        if wrong:
            raise RapidCosimError(f"candidates {', '.join(wrong)}: not in the catalogue ({', '.join(CATALOGUE)})")
        if self.max_effects < 1:
            raise RapidCosimError(f"max_effects must be at least 1, got {self.max_effects}")
        if self.model_name is not None and not re.fullmatch(r"iGrGen\.Diagnosed\.[A-Za-z_][A-Za-z0-9_]*",
                                                             self.model_name):
            raise ConfigError(f"model name {self.model_name!r}: iGrGen.Diagnosed.<Identifier> (a Modelica class "
                              "of the package's Diagnosed folder)", None, "--model-name")


def split_holdout(experiments: Sequence[Experiment], holdout: Sequence[str]) -> tuple[list, list]:
    """(training, held out) by the names of the experiments to hold out."""
    names = [e.name for e in experiments]
    unknown = [h for h in holdout if h not in names]
    if unknown:
        close = close_matches(unknown[0], names, n=1)
        raise ConfigError(f"held-out {', '.join(unknown)}: not among the experiments ({', '.join(names)})"
                          + (f"; did you mean {close[0]!r}?" if close else ""), None, "--holdout")
    training = [e for e in experiments if e.name not in holdout]
    if not training:
        raise ConfigError(f"every experiment is held out ({', '.join(names)}): keep at least one to fit on", None,
                          "--holdout")
    return training, [e for e in experiments if e.name in holdout]


def _fit_job(job, ctx: "Context", options: RunOptions) -> CandidateFit:
    """Worker: fit one candidate ``(spec, start)`` (what :meth:`Context.fit_many` maps)."""
    spec, start = job
    return fit_candidate(spec, ctx.training, ctx.workdir, options=options, start=start, source=ctx.source,
                         fmus=ctx.fmus, searches=ctx.options.searches, noise=ctx.models)


class Context:
    """The fits made so far, by candidate label (each fitted once), with the campaign's
    noise: each recorder's model (``noise_fits``), the tests' floors (``noise``) and the
    adequacy null's shared replicates (``null``, made with the base fit)."""

    def __init__(self, training, heldout, workdir, options: DiagnoseOptions, source: ModelSource,
                 log: Callable[[str], None], noise_fits: dict | None = None, kept: KeptReplicates | None = None):
        self.training, self.heldout = list(training), list(heldout)
        self.workdir, self.options = Path(workdir), options
        options.engine.warm()  # the candidates' workers start while the noise and the base model are fitted here
        # the user's models: a named model may be written into the user's own package (source.users_package),
        # never into the one shipped inside rapid_cosim (an installed wheel's files are not the user's)
        self.user_source, self.log = source, log
        # candidates are generated into, and built from, a copy in the work folder
        self.source = replace(source, package=self.workdir / "package" / source.package_path.name,
                              fmu_dir=self.workdir / "fmus")
        shutil.copytree(source.package_path, self.source.package, dirs_exist_ok=True)  # refreshed on every run
        self.judging = Judge.of(self.training + self.heldout, noise_fits)
        self.noise_fits, self.noise = self.judging.noise_fits, self.judging.floors
        self.models = {name: fit.model for name, fit in self.noise_fits.items()}
        self.fits: dict[str, CandidateFit] = {}
        self.fmus: dict = {}  # FMUs by model, built or loaded once for all candidates
        self._predictions: dict[tuple, tuple] = {}
        self._adequacy: dict[tuple, Adequacy] = {}
        self.kept = kept  # replicates made before (an identification's other part), taken where the same
        self.run_options = RunOptions(method=options.method, seed=options.seed, engine=options.engine,
                                      estimator_options=options.estimator_options, runner=options.runner).check()
        # Candidates are independent fits: with local workers each is fitted in a worker
        # process (its batches then run in that process); on a dask cluster they are
        # fitted here, one after the other, and their batches go to the cluster.
        self.parallel = options.engine.processes

    @property
    def bases(self) -> list[str]:
        return sorted({e.model for e in self.training + self.heldout})

    def fit(self, spec: CandidateSpec, start: dict | None = None) -> CandidateFit:
        return self.fit_many([(spec, start)])[0]

    def fit_many(self, items) -> list[CandidateFit]:
        """Each ``(spec, start)`` fitted once (``start`` None: the base model's optimum with
        the effects off), in worker processes when the options give several."""
        todo = {}
        for spec, start in items:
            for base in self.bases:  # benches not in the package are generated into the work copy
                if is_generated(bench_name(spec.effects, base)):
                    write_bench(self.source.package, spec.effects, bench_name(spec.effects, base), base=base,
                                description=f"{BASES[base]} with {', '.join(spec.effects)} (candidate)")
            if spec.label not in self.fits and spec.label not in todo:
                todo[spec.label] = (spec, start if start is not None else default_start(spec, self.base_parameters()))
        jobs = list(todo.values())
        for spec, _ in jobs:
            self.log(f"  fitting {spec.label} ...")
        if self.parallel and len(jobs) > 1:
            options_engine = self.options.engine
            # built once, not per worker
            self.source.build(sorted({bench_name(spec.effects, b) for spec, _ in jobs for b in self.bases}))
            payload = WholeFits(_fit_job, tuple(jobs), self, replace(self.run_options, engine=options_engine.single()))
            fits = map_fits(options_engine, payload)
        else:
            run_options = self.run_options
            if self.parallel and len(jobs) == 1 and jobs[0][0].label == BASE:
                # the base model, the first fit: here, as a worker fits a candidate, not batch
                # by batch on workers that are still starting (a set's score does not depend
                # on where it is computed, so the numbers are the same)
                run_options = replace(run_options, engine=self.options.engine.single())
            fits = fit_here(WholeFits(_fit_job, tuple(jobs), self, run_options))
        for fit in fits:
            self.fits[fit.spec.label] = fit
            reached = fit.reached_best()
            self.log(f"    {fit.spec.label}: fitness {fit.fitness:.4g}, BIC {bic(fit, self.noise):.1f}, "
                     f"{fit.nfev} simulations" + (f", best reached by {reached} of {fit.waterfall.size} starts"
                                                  if reached is not None else ""))
            if self.judging.null is None:
                self._make_null(fit)
        return [self.fits[spec.label] for spec, _ in items]

    def __getstate__(self):  # what a worker needs to fit candidates (not the fits, the null, the log)
        keep = ("training", "workdir", "source", "fmus", "models", "options")
        return {k: self.__dict__[k] for k in keep}

    def _make_null(self, fit: CandidateFit) -> None:
        """The noise replicates of every test, whitened as the fitness whitens them."""
        exps = list(fit.inputs.experiments)
        if self.heldout:
            exps += list(self._heldout_inputs(fit).experiments)
        self.judging.replicate(exps, self.options.replicates, seed=self.options.seed, kept=self.kept,
                               engine=self.options.engine)

    def base_parameters(self) -> dict[str, float] | None:
        base = self.fits.get(BASE)
        return dict(base.parameters) if base else None

    def tests(self, fit: CandidateFit) -> dict:
        """Residuals on the training tests and, predicted, on the held-out ones."""
        tests = dict(fit.tests)
        if self.heldout:
            tests.update(self.predict(fit))
        return tests

    def predict(self, fit: CandidateFit) -> dict:
        """Residuals of the held-out tests at the training calibration; kept, as the
        verdict and the report ask for the same fits more than once."""
        if not self.heldout:
            return {}
        return self._prediction(fit)[0]

    def _key(self, fit: CandidateFit) -> tuple:
        return fit.spec, tuple(sorted(fit.parameters.items()))

    def _heldout_inputs(self, fit: CandidateFit):
        return candidate_inputs(self.workdir / "heldout" / fit.spec.slug, self.heldout, fit.spec,
                                source=self.source, fmus=self.fmus, noise=self.models)

    def _prediction(self, fit: CandidateFit) -> tuple:
        key = self._key(fit)
        if key not in self._predictions:
            inputs = self._heldout_inputs(fit)
            x = np.array([fit.parameters[n] for n in inputs.problem.names])
            self._predictions[key] = (residuals_at(inputs, x), inputs, x)
        return self._predictions[key]

    def adequacy(self, fit: CandidateFit) -> Adequacy:
        """Does ``fit`` leave only noise, on every test (held-out ones predicted)? With the
        null computed for its own fitted parameters (:mod:`.adequacy`)."""
        key = self._key(fit)
        if key not in self._adequacy:
            if self.judging.null is None:
                self._make_null(fit)
            parts = [(fit.inputs, [fit.parameters[n] for n in fit.inputs.problem.names])]
            if self.heldout:
                _, inputs, xh = self._prediction(fit)
                parts.append((inputs, xh))
            self._adequacy[key] = self.judging.judge(self.tests(fit), jacobians_at(*parts),
                                                     [e.name for e in self.training])
        return self._adequacy[key]
