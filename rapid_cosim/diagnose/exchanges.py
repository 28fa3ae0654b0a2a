"""Pairs of estimated parameters the tests fit either way round: their values swapped
change the whitened fit by less than a unit (a valve lag and a reheater time constant
are two values to a step response, not which is which). The intervals of such a pair
are given at both optima (:mod:`.intervals`), and the identifiability report names
them (:mod:`rapid_cosim.structures.identifiability`)."""

from __future__ import annotations

import numpy as np

from ..fitting.objective import evaluate_in_detail

SAME_FIT = 0.1  # a change of the whitened sum of squares smaller than this is no change of the fit
DISTINCT = 0.01  # values closer than this (relative) are one value: swapping them is no test


def whitened_residual(inputs, x, noise) -> np.ndarray:
    """The tests' whitened residuals at ``x``, end to end (masked samples carry no
    information and are left out)."""
    parts = []
    for r in evaluate_in_detail(inputs.problem, inputs.fmus, np.asarray(x, dtype=float)):
        (column,) = r.fit.residuals
        parts.append(noise[r.experiment.name].whiten(r.fit.residuals[column]))
    return np.concatenate(parts)


def exchanges(inputs, x: np.ndarray, noise) -> tuple[tuple[str, str, float], ...]:
    """The pairs of estimated parameters whose values, swapped (each inside the other's
    bounds, the two distinct), change the whitened sum of squares by under SAME_FIT, with
    that change: one simulation per test and candidate pair."""
    x = np.asarray(x, dtype=float)
    space = inputs.problem.space
    base = float(np.sum(whitened_residual(inputs, x, noise) ** 2))
    found = []
    for i in range(x.size):
        for j in range(i + 1, x.size):
            inside = space.lower[j] <= x[i] <= space.upper[j] and space.lower[i] <= x[j] <= space.upper[i]
            if not inside or abs(x[i] - x[j]) <= DISTINCT * max(abs(x[i]), abs(x[j])):
                continue
            swapped = x.copy()
            swapped[[i, j]] = x[[j, i]]
            change = float(np.sum(whitened_residual(inputs, swapped, noise) ** 2)) - base
            if abs(change) < SAME_FIT:
                found.append((space.names[i], space.names[j], change))
    return tuple(found)
