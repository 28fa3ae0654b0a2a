"""About how many simulations a run takes and how long they take on this machine: what
``rapid-cosim check`` says before a user commits minutes to a run.

Counts are rough on purpose: the methods stop when they converge. They come from the
estimators' own settings (particles, iterations, starts) where those fix the count, and
from what the bundled examples took otherwise (``make bench-identify`` measures them).
The time of one simulation is measured here, on each experiment's own bench and
recording, after a first call that loads the model.
"""

from __future__ import annotations

import time
from dataclasses import fields
from typing import Sequence

from ..compiler.source import ModelSource
from ..estimators.chain import REGISTRY, parse_method

# What the bundled examples took (make identify, make identify-steam, make identify-electrical:
# explanation candidates 300-800 simulations each, pairs 600-2000, a structure 500-1500)
PER_CANDIDATE, PER_PAIR, PER_STRUCTURE = 600, 900, 900
PLAYBACK_EXTRA = 2  # a record's playback: the record and one step per parameter, per test


def _option(method: str, name: str, default: int) -> int:
    cls = REGISTRY[method][1]
    found = {f.name: f.default for f in fields(cls)}
    value = found.get(name, default)
    return int(value) if isinstance(value, (int, float)) and value else default


def method_simulations(method: str, dim: int) -> int:
    """About how many simulations ``method`` (a chain such as ``pf:10+nm``) takes on
    ``dim`` estimated parameters."""
    total = 0
    for stage in parse_method(method):
        iterations = stage.max_iter or _option(stage.name, "max_iter", 50)
        if stage.name in ("pf", "pso", "smc"):
            total += (min(iterations, 60) + 1) * _option(stage.name, "n_particles", 50)
        elif stage.name == "ms":
            starts = 4 + 2 * dim
            total += 24 * dim + starts * 12 * (dim + 1)
        elif stage.name == "scan":
            total += 20 * dim
        else:  # nm, gd: local searches
            total += 25 * (dim + 1)
    return total


def identify_simulations(candidates: int, structures: int) -> int:
    """About how many simulations one identification takes: the effect catalogue's
    candidates and their pairs, then every structure fit."""
    return PER_CANDIDATE * (candidates + 1) + PER_PAIR * max(candidates - 1, 0) + PER_STRUCTURE * structures


def seconds_per_simulation(experiments: Sequence, *, source: ModelSource = ModelSource(), batch: int = 8) -> float:
    """Wall time of one simulation of every experiment (their sum: one parameter set of a
    joint fit), each on its bench and recording in a batch of ``batch`` sets as the
    estimators run them, measured after a first call."""
    import numpy as np

    from ..fitting.objective import ExperimentBatch

    total = 0.0
    for exp in experiments:
        fmu = source.fmu(exp.model)
        specs = list(exp.estimate)
        x = [s.start if s.start is not None else 0.5 * (s.min + s.max) for s in specs]
        run = ExperimentBatch(exp, fmu, [(s.name, j) for j, s in enumerate(specs)])
        X = np.tile(np.asarray(x, dtype=float), (batch, 1))
        run(X[:1])
        best = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            run(X)
            best = min(best, (time.perf_counter() - t0) / batch)
        total += best
    return total


def duration(seconds: float) -> str:
    if seconds < 1:
        return "under a second"
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
