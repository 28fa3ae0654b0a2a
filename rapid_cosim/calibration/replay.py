"""Replay: a run is resumed by executing it again from the start with the archived
evaluations served from a cache, and re-run by executing it with the cache empty; in
both, every iteration is compared with the archive's."""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..estimators.base import Evaluations, Iteration
from ..fitting.objective import ProblemObjective


class RecordingObjective:
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

    def residuals(self, X: np.ndarray) -> tuple[Evaluations, np.ndarray]:
        """Evaluations with residual vectors (least-squares methods). The archive keeps no
        residual vectors, so these rows are simulated even on a replay (a multistart's
        whole design among them, which it scores with residual vectors to take its starts
        from); they are deterministic, so a resumed run still ends where the uninterrupted
        one would."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        ev, R = self.objective.residuals(X)
        self.simulated += X.shape[0]
        for j, row in enumerate(X):
            self.known.setdefault(row.tobytes(), (float(ev.fitness[j]), bool(ev.failed[j]), ev.rssd[j].copy()))
        return ev, R

    def rssd_of(self, X: np.ndarray) -> np.ndarray:
        return np.vstack([self.known[row.tobytes()][2] for row in np.atleast_2d(X)])


def same_iteration(a: Iteration, b: Iteration) -> str | None:
    """Why two iterations differ (ignoring wall time), or None if they are identical."""
    checks = [("stage", a.stage == b.stage), ("index", a.index == b.index),
              ("particles", np.array_equal(a.x, b.x)), ("fitness", np.array_equal(a.fitness, b.fitness)),
              ("weights", np.array_equal(a.weights, b.weights)), ("failed", np.array_equal(a.failed, b.failed)),
              ("best", np.array_equal(a.best_x, b.best_x) and a.best_fitness == b.best_fitness),
              ("n_sims", a.n_sims == b.n_sims), ("rng state", a.rng_state == b.rng_state)]
    bad = [name for name, ok in checks if not ok]
    return ", ".join(bad) if bad else None
