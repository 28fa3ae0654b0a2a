"""Chains of methods, the paper's two-step scheme (section 3): a global stage for a few
iterations, then a local one from its best point, written as a method string::

    pf:10+nm    pso:10+nm    smc    gd    pf:5+pso:5+gd    pso:10+nm+scan+nm

``A:n`` caps stage A at n iterations (its options' ``max_iter``); a stage without ``:n``
runs with its own options. Each stage starts from the best point found so far (``x0``).
The chain reports one result: iteration indices, ``n_sims`` and ``wall_time`` continue
across stages, ``best_x``/``best_fitness`` of each iteration are the best of the whole
chain so far, and the callback sees the iterations renumbered that way.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Mapping

import numpy as np

from .base import EstimationResult, Iteration, IterationCallback, Objective, SearchSpace
from .gradient import GDOptions, gradient_descent
from .multistart import MSOptions, multistart
from .nelder_mead import NMOptions, nelder_mead
from .pf import PFOptions, particle_filter
from .pso import PSOOptions, pso
from .scan import ScanOptions, coordinate_scan
from .smc import LogLikelihood, SMCOptions, smc

REGISTRY: dict[str, tuple[Callable[..., EstimationResult], type]] = {
    "pf": (particle_filter, PFOptions),
    "smc": (smc, SMCOptions),
    "pso": (pso, PSOOptions),
    "nm": (nelder_mead, NMOptions),
    "gd": (gradient_descent, GDOptions),
    "scan": (coordinate_scan, ScanOptions),
    "ms": (multistart, MSOptions),
}

_SYNTAX = "write stages as NAME or NAME:N joined by '+', e.g. 'pf:10+nm'"


@dataclass(frozen=True)
class Stage:
    """One stage of a chain: a registered method and an optional iteration cap."""

    name: str
    max_iter: int | None = None


def parse_method(text: str) -> tuple[Stage, ...]:
    """Parse a method string such as ``pf:10+nm`` into stages; ``ValueError`` says what is
    wrong and what is allowed."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"empty method {text!r}; {_SYNTAX}; methods: {', '.join(REGISTRY)}")
    stages = []
    for k, part in enumerate(text.split("+"), start=1):
        part = part.strip()
        if not part:
            raise ValueError(f"empty stage {k} in method {text!r}; {_SYNTAX}")
        name, sep, count = (s.strip() for s in part.partition(":"))
        name = name.lower()
        if name not in REGISTRY:
            raise ValueError(
                f"unknown method {name!r} in {text!r}; allowed: {', '.join(REGISTRY)}")
        if not sep:
            stages.append(Stage(name))
            continue
        if not count.isdigit() or int(count) < 1:
            raise ValueError(
                f"bad iteration count {count!r} for {name!r} in {text!r}; "
                f"it must be a positive integer, e.g. '{name}:10'")
        stages.append(Stage(name, int(count)))
    return tuple(stages)


def _offset(it: Iteration, index: int, n_sims: int, wall: float,
            best: tuple[np.ndarray, float] | None) -> Iteration:
    """``it`` renumbered into the chain, with the chain's best if that is better."""
    changes = dict(index=it.index + index, n_sims=it.n_sims + n_sims,
                   wall_time=it.wall_time + wall)
    if best is not None and best[1] < it.best_fitness:
        changes.update(best_x=best[0].copy(), best_fitness=best[1])
    return replace(it, **changes)


def run_chain(
    objective: Objective,
    space: SearchSpace,
    method: str,
    *,
    options: Mapping[str, object] | None = None,
    rng: np.random.Generator,
    callback: IterationCallback | None = None,
    x0=None,
    log_likelihood: LogLikelihood | None = None,
) -> EstimationResult:
    """Run the stages of ``method`` in order and merge them into one result.

    ``options`` maps method names to their options dataclass (defaults otherwise);
    ``log_likelihood`` is needed when the chain contains ``smc``. The result's uncertainty
    is the last SMC stage's posterior, if any.
    """
    stages = parse_method(method)
    options = dict(options or {})
    for name, opts in options.items():
        if name not in REGISTRY:
            raise ValueError(
                f"options given for unknown method {name!r}; allowed: {', '.join(REGISTRY)}")
        cls = REGISTRY[name][1]
        if not isinstance(opts, cls):
            raise ValueError(
                f"options[{name!r}] must be a {cls.__name__}, got {type(opts).__name__}")
    if log_likelihood is None and any(s.name == "smc" for s in stages):
        raise ValueError("method 'smc' needs log_likelihood (the caller's noise model)")

    history: list[Iteration] = []
    best: tuple[np.ndarray, float] | None = None
    nfev = n_failed = 0
    wall = 0.0
    reasons, uncertainty = [], None
    for k, stage in enumerate(stages, start=1):
        func, cls = REGISTRY[stage.name]
        opts = options.get(stage.name) or cls()
        if stage.max_iter is not None:
            opts = replace(opts, max_iter=stage.max_iter)
        index0, sims0, wall0, best0 = len(history), nfev, wall, best

        def forward(it: Iteration) -> None:
            it = _offset(it, index0, sims0, wall0, best0)
            history.append(it)
            if callback is not None:
                callback(it)

        kwargs = {"log_likelihood": log_likelihood} if stage.name == "smc" else {}
        res = func(objective, space, options=opts, rng=rng, callback=forward, x0=x0, **kwargs)
        nfev, n_failed, wall = nfev + res.nfev, n_failed + res.n_failed, wall + res.wall_time
        if best is None or res.fun < best[1]:
            best = (res.x.copy(), float(res.fun))
        x0 = best[0]
        uncertainty = res.uncertainty or uncertainty
        reasons.append(f"{stage.name} (stage {k}/{len(stages)}): {res.stop_reason}")

    return EstimationResult(
        method=method,
        names=space.names,
        x=best[0],
        fun=best[1],
        nfev=nfev,
        nit=len(history),
        wall_time=wall,
        stop_reason="; ".join(reasons),
        history=tuple(history),
        n_failed=n_failed,
        uncertainty=uncertainty,
    )
