"""The quiet stretches of a campaign: where a recording holds noise and nothing else.

Before a staged step, and once the response has settled after a step or a return, the
recorded power is the dispatch plus noise (plus a slow drift a trend absorbs). A recorded
event is quiet only before it. Every stretch of every test from one recorder is pooled
(:mod:`.estimate`): a 10 s pre-step window holds about ten independent values of a slow
component with a correlation time near 1 s, too few to estimate it alone.

Settled tails are cut into chunks of at most :data:`TAIL_CHUNK_S`, each with its own
quadratic trend: a response still creeping back (a reheat stage, a load controller's
withdrawal) is a slow curve that a quadratic over 20 s follows to well under the noise,
while the noise's correlation time (about a second) is far shorter. The estimator accounts
for the trends it removes (REML), so removing them costs information, not bias.

A stretch runs across a masked sample or two (a frame a PMU flagged invalid, a blank), as
it runs across a dropped frame: both are whitened as if the next sample followed at one
step, a shift of one frame against a correlation time of 20-60 frames. Cutting there
instead cost far more: 0.5 % of frames flagged at 30 frames/s cut a 10 s pre-event
window into pieces of a few seconds, each with its own trend, and the slow component's
correlation time came out at 6.5 s where the unflagged recording gave 1.4 s (its standard
error three times as large). A longer masked run (:data:`MAX_MASKED_RUN`) still cuts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, Sequence

import numpy as np


class Recorded(Protocol):
    """What the noise model reads of an experiment (a
    :class:`rapid_cosim.experiment.Experiment` is one), named without importing it: the
    noise model sits below the experiments whose configs hold one."""

    name: str
    data: Any
    fixed: dict
    inputs: tuple
    measured: Any
    outputs: dict
    pre_step_end: float | None
    weights: dict
    window: tuple

    def windowed_data(self) -> Any: ...

SETTLE_S = 30.0  # after a move, the response is taken as settled this much later
TAIL_CHUNK_S = 20.0
MIN_SAMPLES = 20  # a shorter run of valid samples is not used
MAX_MASKED_RUN = 2  # masked samples in a row that a stretch runs across (see the module docstring)


@dataclass(frozen=True, eq=False)
class QuietStretch:
    """Valid samples of one test's compared output where nothing moves, with no gap
    longer than :data:`MAX_MASKED_RUN` masked samples."""

    test: str
    kind: str  # "pre-step", "settled" or "pre-event"
    time: np.ndarray
    values: np.ndarray
    trend_order: int  # polynomial degree the stretch's trend is removed with

    @property
    def dt(self) -> float:
        return float(np.median(np.diff(self.time)))

    def regressors(self) -> np.ndarray:
        """(n, order + 1): the trend's polynomial basis, centred and scaled."""
        t = self.time - self.time.mean()
        span = max(float(np.ptp(t)), 1e-9)
        return np.column_stack([(t / span) ** j for j in range(self.trend_order + 1)])

    def detrended(self) -> np.ndarray:
        X = self.regressors()
        coef, *_ = np.linalg.lstsq(X, self.values, rcond=None)
        return self.values - X @ coef


def output_of(exp: Recorded) -> str:
    weighted = [o for o in exp.outputs if exp.weights[o] > 0]
    if len(weighted) != 1:
        raise ValueError(f"{exp.name}: the noise model is estimated for one compared output; it has "
                         f"{len(weighted)} ({', '.join(weighted)})")
    return weighted[0]


def quiet_windows(exp: Recorded, settle: float = SETTLE_S) -> list[tuple[str, float, float, int]]:
    """(kind, start, end, trend order) of the test's quiet windows, in seconds."""
    data = exp.windowed_data()
    t0, t1 = float(data.time[0]), float(data.time[-1]) + 1e-9
    if exp.inputs:  # a recorded event: quiet only before it
        end = exp.pre_step_end
        return [("pre-event", t0, end, 1)] if end is not None else []
    t_step = exp.fixed.get("src.t_step", exp.pre_step_end)
    if t_step is None:
        return []
    windows = [("pre-step", t0, float(t_step), 1)]
    moves = [float(t_step)]
    t_return = exp.fixed.get("src.t_return")
    if t_return is not None and float(t_return) < t1:
        moves.append(float(t_return))
    for k, move in enumerate(moves):
        start = move + settle
        end = moves[k + 1] if k + 1 < len(moves) else t1
        while end - start >= 0.5 * TAIL_CHUNK_S:
            stop = min(start + TAIL_CHUNK_S, end)
            if end - stop < 0.5 * TAIL_CHUNK_S:
                stop = end  # no short last chunk
            windows.append(("settled", start, stop, 2))
            start = stop
    return windows


def quiet_stretches(experiments: Sequence[Recorded], settle: float = SETTLE_S,
                    tails: bool = True) -> list[QuietStretch]:
    """Every quiet stretch of the experiments (``tails=False``: the pre-step ones only)."""
    out = []
    for exp in experiments:
        output = output_of(exp)
        values, valid = exp.measured(output)
        t = exp.data.time
        lo, hi = exp.window
        for kind, start, end, order in quiet_windows(exp, settle):
            if kind == "settled" and not tails:
                continue
            use = valid & (t >= max(start, lo)) & (t < min(end, hi + 1e-9))
            idx = np.flatnonzero(use)
            if idx.size == 0:
                continue
            for run in np.split(idx, np.flatnonzero(np.diff(idx) > MAX_MASKED_RUN + 1) + 1):
                if run.size >= MIN_SAMPLES:
                    out.append(QuietStretch(exp.name, kind, t[run].copy(), values[run].astype(float), order))
    return out


def recorder_groups(experiments: Sequence[Recorded], tolerance: float = 0.1) -> list[list[str]]:
    """Tests grouped by recorder: the same median sample interval within ``tolerance``
    (the field campaign's 10 Hz and 25 Hz recorders, say)."""
    groups: list[tuple[float, list[str]]] = []
    for exp in experiments:
        dt = float(np.median(np.diff(exp.windowed_data().time)))
        for g in groups:
            if abs(g[0] - dt) <= tolerance * g[0]:
                g[1].append(exp.name)
                break
        else:
            groups.append((dt, [exp.name]))
    return [names for _, names in groups]
