"""Input tables: the values an FMU's inputs take over time (a recorded frequency, say).

Rows of time and values, time non-decreasing. Between rows the values are linear in
time; a time written twice is a step (the first row holds the value before it, the
second the value after), which both runners take as a time event. Before the first row
and after the last the values are held.

While the integrator works towards a step it may evaluate the model past it; there the
input keeps its value before the step (``limit_row``), as an FMU's own conditions only
switch in event mode. The compiled runner (``runner.c``) implements the same rules; the
two must agree, which the tests check.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import ParameterError


@dataclass(frozen=True, eq=False)
class InputTable:
    time: np.ndarray  # (r,)
    names: tuple[str, ...]
    values: np.ndarray  # (r, k)

    def __post_init__(self):
        t = np.ascontiguousarray(self.time, dtype=float)
        v = np.ascontiguousarray(self.values, dtype=float)
        if v.ndim == 1:
            v = v[:, None]
        if t.ndim != 1 or t.size < 1 or v.shape != (t.size, len(self.names)):
            raise ParameterError(f"an input table needs one time per row and one column per input; got time "
                                 f"{t.shape} and values {v.shape} for {len(self.names)} input(s)")
        if not np.all(np.isfinite(t)):
            raise ParameterError(f"input time is not finite at row {int(np.argmin(np.isfinite(t)))}")
        bad = np.flatnonzero(np.diff(t) < 0)
        if bad.size:
            raise ParameterError(f"input time decreases at row {bad[0] + 1} ({t[bad[0]]:g} s, then "
                                 f"{t[bad[0] + 1]:g} s)")
        same = np.flatnonzero((t[2:] == t[1:-1]) & (t[1:-1] == t[:-2]))
        if same.size:
            raise ParameterError(f"input time {t[same[0]]:g} s is written three times; a step writes it twice")
        rows, cols = np.nonzero(~np.isfinite(v))
        if rows.size:
            raise ParameterError(f"input {self.names[cols[0]]} is not finite at row {rows[0]} "
                                 f"({t[rows[0]]:g} s); a model cannot run through a gap in its input")
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "values", v)
        object.__setattr__(self, "names", tuple(self.names))

    @classmethod
    def from_columns(cls, time, columns: Mapping[str, np.ndarray]) -> "InputTable":
        names = tuple(columns)
        return cls(np.asarray(time, dtype=float), names,
                   np.column_stack([np.asarray(columns[n], dtype=float) for n in names]) if names
                   else np.zeros((np.size(time), 0)))

    @property
    def steps(self) -> np.ndarray:
        """Row index of the first row of each step."""
        return np.flatnonzero(self.time[1:] == self.time[:-1])

    def next_step(self, t: float) -> int:
        """First row of the next step strictly after ``t``, or -1."""
        s = self.steps
        ahead = s[self.time[s] > t]
        return int(ahead[0]) if ahead.size else -1

    def at(self, t: float, limit_row: int = -1) -> np.ndarray:
        """The values at ``t``; at or past ``time[limit_row]``, the value before that step."""
        tt, v = self.time, self.values
        if limit_row >= 0 and t >= tt[limit_row]:
            return v[limit_row].copy()
        if t >= tt[-1]:
            return v[-1].copy()
        if t <= tt[0]:
            return v[int(np.searchsorted(tt, t, side="right")) - 1 if t == tt[0] else 0].copy()
        hi = int(np.searchsorted(tt, t, side="right"))
        lo = hi - 1
        w = (t - tt[lo]) / (tt[hi] - tt[lo])
        return v[lo] + w * (v[hi] - v[lo])
