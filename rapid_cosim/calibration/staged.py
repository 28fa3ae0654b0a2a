"""The staged tests as experiments: each test calibrated with the paper's two chains
(PSO10+NM and PF10+NM, section 3), one joint Bayesian fit of R and Ts over tests 1-8,
and the Laplace approximation at each test's optimum that the consistency check needs.

Everything here runs estimations or simulations and writes archives (or JSON beside
them); tables and figures are made from those files by :mod:`rapid_cosim.report`.

Layout under a results folder (default ``results/``)::

    <test>/pso10+nm.h5  <test>/pf10+nm.h5    one archive per test and method
    <test>/<test>.png                        the test's fit figure (report)
    joint/smc.h5                             the joint SMC run over tests 1-8
    joint/laplace.json                       per-test Laplace approximations
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from . import (RunInputs, RunOptions, ensure_run, inputs_from_archive, inputs_from_configs,
                           log_likelihood_for)
from ..archive import RunArchive
from ..data import ar1_inflation, noise_level
from ..errors import RapidCosimError
from ..estimators.base import EstimationResult
from ..estimators.laplace import laplace
from ..estimators.uncertainty import Uncertainty
from ..compiler.source import ModelSource
from ..fitting.engine import EngineSpec
from ..fitting.objective import ProblemObjective


@dataclass(frozen=True)
class Method:
    """One of the paper's two chains with the particle count used here."""

    key: str  # archive file stem
    label: str  # as the paper writes it
    chain: str  # estimator chain (rapid_cosim.estimators.chain)
    options: dict[str, dict[str, Any]] = field(default_factory=dict)

    def run_options(self, seed: int, engine: EngineSpec) -> RunOptions:
        return RunOptions(method=self.chain, seed=seed, engine=engine, estimator_options=self.options)


# Particle counts: the paper gives none. 30 particles for the swarm (PSO's usual 20-40
# for a few parameters), 50 for the filter (Algorithm 1 needs enough particles to prune
# half and still cover the box). Both first stages take 10 iterations, as in the paper;
# NM then runs to scipy's tolerances. One run takes 3-10 s on 2 cores.
METHODS: tuple[Method, ...] = (
    Method("pso10+nm", "PSO10+NM", "pso:10+nm", {"pso": {"n_particles": 30}}),
    Method("pf10+nm", "PF10+NM", "pf:10+nm", {"pf": {"n_particles": 50}}),
)

# The joint fit: 2 parameters, 8 experiments per evaluation. 100 particles with 2 moves
# per tempering stage keep it to a few minutes on 2 cores (see README, "Staged tests").
JOINT_OPTIONS = {"smc": {"n_particles": 100, "n_mcmc_steps": 2}}
JOINT_METHOD = "smc"


def method(key: str) -> Method:
    for m in METHODS:
        if m.key == key:
            return m
    raise RapidCosimError(f"unknown method {key!r}; methods: {', '.join(m.key for m in METHODS)}")


def archive_path(results: str | Path, test: str, method_key: str) -> Path:
    return Path(results) / test / f"{method_key}.h5"


def archived_tests(results: str | Path) -> list[str]:
    """Tests with an archive of either chain under ``results`` (not the joint fit, nor a
    diagnosis, which keep other archives there), in natural order."""
    found = {p.parent.name for m in METHODS for p in Path(results).glob(f"*/{m.key}.h5")}
    return sorted(found, key=natural_key)


def joint_archive_path(results: str | Path) -> Path:
    return Path(results) / "joint" / "smc.h5"


def parse_tests(spec: str, prefix: str = "test") -> list[str]:
    """``"1-8"`` -> test1..test8; ``"1,3,9-10"``; names (``test2``) pass through."""
    names: list[str] = []
    for part in (p.strip() for p in spec.split(",")):
        if not part:
            continue
        m = re.fullmatch(r"(\d+)\s*-\s*(\d+)", part)
        if m:
            lo, hi = int(m.group(1)), int(m.group(2))
            if lo > hi:
                raise RapidCosimError(f"bad test range {part!r}: {lo} > {hi}")
            names += [f"{prefix}{k}" for k in range(lo, hi + 1)]
        elif part.isdigit():
            names.append(f"{prefix}{int(part)}")
        elif re.fullmatch(r"[A-Za-z0-9_.\-]+", part):
            names.append(part)
        else:
            raise RapidCosimError(f"bad test list {spec!r}: write e.g. 1-8 or 1,3,9-10")
    if not names:
        raise RapidCosimError(f"no tests in {spec!r}")
    return list(dict.fromkeys(names))


def natural_key(name: str):
    """test2 before test10."""
    m = re.fullmatch(r"(.*?)(\d+)", name)
    return (m.group(1), int(m.group(2))) if m else (name, -1)


# --------------------------------------------------------------------------- one test


@dataclass(frozen=True)
class StagedRun:
    test: str
    method: Method
    archive: Path
    result: EstimationResult
    action: str  # 'new', 'resumed' or 'archived' (see ensure_run)


def run_staged_test(config: str | Path, *, results: str | Path = "results", seed: int = 1,
                    engine: EngineSpec = EngineSpec(), methods: Sequence[Method] = METHODS,
                    progress: bool = True, source: ModelSource = ModelSource()) -> list[StagedRun]:
    """Both chains on one staged test, make-like (a finished archive of the same run is
    reused, an interrupted one resumed)."""
    inputs = inputs_from_configs([config], source=source)
    test = inputs.experiments[0].name
    runs = []
    for m in methods:
        path = archive_path(results, test, m.key)
        result, action = ensure_run(inputs, m.run_options(seed, engine), path, progress=progress)
        if result.nfev and result.n_failed == result.nfev:
            raise RapidCosimError(f"{path}: every one of the {result.nfev} simulations of {m.label} on {test} "
                                  f"failed, so the run found nothing; 'rapid-cosim show {path}' summarises it. "
                                  f"Remove the archive to run again once the simulator works.")
        runs.append(StagedRun(test, m, path, result, action))
    return runs


# --------------------------------------------------------------------------- the joint fit


def run_joint(configs: Sequence[str | Path], *, results: str | Path = "results", seed: int = 1,
              engine: EngineSpec = EngineSpec(), options: dict[str, dict[str, Any]] | None = None,
              progress: bool = True, source: ModelSource = ModelSource()) -> tuple[Path, EstimationResult, str]:
    """One SMC fit of shared R, Ts over the given tests (offsets profiled per test),
    archived (make-like) in ``<results>/joint/smc.h5``; ``options`` override
    :data:`JOINT_OPTIONS` key by key."""
    inputs = inputs_from_configs(configs, source=source)
    merged = {m: dict(kw) for m, kw in JOINT_OPTIONS.items()}
    for m, kw in (options or {}).items():
        if m != JOINT_METHOD:
            raise RapidCosimError(f"the joint fit runs {JOINT_METHOD}; options for {m!r} do not apply")
        merged.setdefault(m, {}).update(kw)
    opts = RunOptions(method=JOINT_METHOD, seed=seed, engine=engine, estimator_options=merged)
    path = joint_archive_path(results)
    result, action = ensure_run(inputs, opts, path, progress=progress)
    return path, result, action


# --------------------------------------------------------------------------- Laplace


@dataclass(frozen=True)
class Laplace:
    """Gaussian approximation of one test's likelihood at its archived optimum.

    ``uncertainty`` is built from the Hessian of the negative log-likelihood
    ``0.5 * M * RSSD / sigma**2`` (white noise of the pre-step level ``sigma``), by
    central differences. ``phi`` is the pre-step lag-1 autocorrelation and
    ``inflation = (1 + phi) / (1 - phi)`` the factor by which AR(1) noise of that
    coefficient inflates the variance of a mean (and, roughly, of a least-squares
    estimate driven by slow residual components): :attr:`inflated` scales by it.
    """

    test: str
    archive: str
    fitness: float
    sigma: float
    n_samples: int
    phi: float
    inflation: float
    uncertainty: Uncertainty

    @property
    def inflated(self) -> Uncertainty:
        return self.uncertainty.scaled(self.inflation)

    def to_json(self) -> dict:
        return {"test": self.test, "archive": self.archive, "fitness": self.fitness, "sigma": self.sigma,
                "n_samples": self.n_samples, "phi": self.phi, "inflation": self.inflation,
                "uncertainty": self.uncertainty.to_json()}

    @classmethod
    def from_json(cls, d: dict) -> "Laplace":
        return cls(d["test"], d["archive"], float(d["fitness"]), float(d["sigma"]), int(d["n_samples"]),
                   float(d["phi"]), float(d["inflation"]), Uncertainty.from_json(d["uncertainty"]))


def laplace_at_optimum(archive: str | Path, *, engine: EngineSpec = EngineSpec(), rel_step: float = 0.5) -> Laplace:
    """Laplace approximation at an archived single-test run's best point (two passes of
    :func:`rapid_cosim.estimators.laplace.laplace`, 18 simulations for R and Ts). A best
    point within a step of a bound is reported in ``at_bound`` (its stencil moved inside)."""
    with RunArchive(archive) as view:
        inputs = inputs_from_archive(view)
        result = view.result()
    if result is None:
        raise RapidCosimError(f"{archive}: the run is not finished")
    problem = inputs.problem
    if len(problem.experiments) != 1:
        raise RapidCosimError(f"{archive}: the Laplace check is per test; this run fits {len(problem.experiments)}")
    exp = problem.experiments[0]
    approx = hessian_uncertainty(inputs, result.x, archive, engine=engine, rel_step=rel_step)
    out = list(exp.outputs)[0]
    col = exp.outputs[out]
    noise = noise_level(exp.data, col, exp.pre_step_end)
    return Laplace(test=exp.name, archive=str(archive), fitness=float(result.fun), sigma=float(exp.noise_sigma[out]),
                   n_samples=exp.windowed_data().n_valid(col), phi=float(noise.phi),
                   inflation=ar1_inflation(noise.phi), uncertainty=approx)


def hessian_uncertainty(inputs: RunInputs, x, where: str | Path, *, engine: EngineSpec = EngineSpec(),
                        rel_step: float = 0.5) -> Uncertainty:
    """The Gaussian (Laplace) approximation of the run's likelihood at ``x``: every
    experiment's white noise at its configured level, the Hessian by central differences."""
    problem = inputs.problem
    loglik = log_likelihood_for(problem)
    if loglik is None:
        missing = [e.name for e in problem.experiments if e.noise_sigma is None]
        raise RapidCosimError(f"{where}: {', '.join(missing) or 'an experiment'} has no noise level "
                              "([fitness] noise), so the likelihood is not known")
    objective = ProblemObjective(problem, inputs.fmus, engine=engine.make())

    def neg_log_likelihood(X):
        ev = objective(X)
        if ev.failed.any():
            raise RapidCosimError(f"{where}: a simulation near the optimum failed")
        return -loglik(ev)

    return laplace(neg_log_likelihood, problem.space, np.asarray(x, dtype=float), rel_step=rel_step)


def laplace_cache(results: str | Path) -> Path:
    return Path(results) / "joint" / "laplace.json"


def ensure_laplace(archives: Sequence[str | Path], cache: str | Path, *, engine: EngineSpec = EngineSpec(),
                   log: Callable[[str], None] = print) -> list[Laplace]:
    """Laplace approximations of the given archives, computed once and kept in ``cache``
    (keyed by archive path and best point: a new run recomputes it)."""
    cache = Path(cache)
    known = {}
    if cache.exists():
        try:
            known = {d["archive"]: Laplace.from_json(d) for d in json.loads(cache.read_text())}
        except (ValueError, KeyError, TypeError):  # a cache of another layout is recomputed
            known = {}
    out = []
    for a in archives:
        with RunArchive(a) as view:
            result = view.result()
        if result is None:
            raise RapidCosimError(f"{a}: the run is not finished")
        lap = known.get(str(a))
        if lap is not None and np.array_equal(lap.uncertainty.mean, result.x):
            out.append(lap)
            continue
        lap = laplace_at_optimum(a, engine=engine)
        log(f"  Laplace at the optimum of {a}: {lap.uncertainty.evaluations} simulations")
        out.append(lap)
    cache.parent.mkdir(parents=True, exist_ok=True)
    cache.write_text(json.dumps([lap.to_json() for lap in out], indent=1) + "\n")
    return out
