"""One output's whitening on the samples a fit scores: the one place a residual meets
its noise model (the fitness, the adequacy null and the criterion all come here).

Which whitener: the stationary ones (:class:`~.model.Whitener`, the Levinson one for a
filtered component) where they are exact, a gap-free run of samples on a regular grid
with no noise derived on the samples' own stamps; otherwise the exact one of
:mod:`.timed`, which takes jittered stamps, missing frames, masked samples and a
:class:`~.timed.DerivedNoise` (the derived ROCOF's in P_e) as they are. Both are built
once per noise model and set of samples and kept (:func:`whitening`).
"""

from __future__ import annotations

import functools
from typing import Sequence

import numpy as np

from .model import RecorderNoise, sample_draws
from .timed import DerivedNoise, TimedWhitener, regular
from .runs import rowwise


class Whitening:
    """Residual rows on ``times`` (the valid scored samples) -> standardised innovations;
    ``rows``: those samples' rows in the record, where a derived component's map is
    defined. ``exact`` says whether the sample-exact (:mod:`.timed`) path is taken."""

    def __init__(self, model: RecorderNoise, times: np.ndarray, rows: np.ndarray | None = None):
        self.model = model
        self.times = np.asarray(times, dtype=float)
        self.rows = None if rows is None else np.asarray(rows, dtype=np.int64)
        self.derived = derived_part(model)
        own = _own_part(model)
        self.exact = self.derived is not None or not regular(self.times)
        if self.exact and (self.derived is None or self.rows is not None) and _only_derived(model):
            self._timed = TimedWhitener(own, self.times, self.derived, self.rows)
        else:
            self.exact, self._timed = False, None
            self._stationary = model.whitener()
            dt = float(np.median(np.diff(self.times))) if self.times.size > 1 else 1.0
            breaks = np.flatnonzero(np.diff(self.times) > 3.0 * dt) + 1
            edges = np.concatenate([[0], breaks, [self.times.size]])
            self.runs = [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]
        self.ones = self.whiten(np.ones((1, self.times.size)))[0]
        self.ones_norm2 = float(self.ones @ self.ones)

    def whiten(self, r: np.ndarray) -> np.ndarray:
        """Standardised innovations of residual rows ``r`` (rows, samples), C-ordered
        (the band product's are transposed; numpy's reductions sum a row in another order
        there, so a set's score would depend on the rows beside it)."""
        r = np.atleast_2d(np.asarray(r, dtype=float))
        if self._timed is not None:
            return np.ascontiguousarray(self._timed.whiten(r))
        out = np.empty(r.shape)
        for a, b in self.runs:
            out[:, a:b] = self._stationary.whiten_runs(r[:, a:b])
        return out

    def residual(self, r: np.ndarray, offset: bool) -> np.ndarray:
        """Whitened residual rows, the GLS offset projected out when ``offset``."""
        e = self.whiten(r)
        if offset:
            e -= np.outer(rowwise(e, self.ones) / self.ones_norm2, self.ones)
        return e

    def offset(self, r: np.ndarray) -> np.ndarray:
        """The GLS offset of each row of ``r``."""
        return rowwise(self.whiten(r), self.ones) / self.ones_norm2

    def sample(self, models: Sequence[RecorderNoise], rng: np.random.Generator) -> np.ndarray:
        """One replicate of the noise per recorder model (drawn for the null: they share
        this whitening's filtered components) at these samples, ``(len(models), n)``: the
        recorder's part at the true stamps, a derived part through its exact map."""
        own = [_own_part(m) for m in models]
        out = sample_draws(own, self.times, rng)
        for f in self.model.filtered:
            if isinstance(f, DerivedNoise) and self.rows is not None:
                out += f.sample_rows(self.rows, rng, len(models))
            else:
                out += f.sample(self.times.size, rng, len(models))
        return out


def derived_part(model: RecorderNoise) -> DerivedNoise | None:
    return next((f for f in model.filtered if isinstance(f, DerivedNoise)), None)


def _own_part(model: RecorderNoise) -> RecorderNoise:
    """The recorder's own white and OU parts (its filtered components left out)."""
    return RecorderNoise(model.sigma_white, model.components, model.dt) if model.filtered else model


def _only_derived(model: RecorderNoise) -> bool:
    """Every filtered component has an exact map (else only the stationary path has it)."""
    return all(isinstance(f, DerivedNoise) for f in model.filtered) and len(model.filtered) <= 1


@functools.lru_cache(maxsize=128)
def _cached(model: RecorderNoise, times: bytes, rows: bytes | None) -> Whitening:
    t = np.frombuffer(times, dtype=np.float64)
    r = None if rows is None else np.frombuffer(rows, dtype=np.int64)
    return Whitening(model, t, r)


def whitening(model: RecorderNoise, times: np.ndarray, rows: np.ndarray | None = None) -> Whitening:
    """:class:`Whitening`, kept per noise model and samples (experiments re-read from their
    configs, as a diagnosis does for every candidate, share it)."""
    t = np.ascontiguousarray(times, dtype=np.float64)
    r = None if rows is None else np.ascontiguousarray(rows, dtype=np.int64)
    return _cached(model, t.tobytes(), None if r is None else r.tobytes())
