"""A recording in memory: one strictly increasing time base, float64 columns with NaN
where a sample is missing, and a validity mask beside each.

Missing samples are *masked*, never interpolated over: a fit simply has fewer samples
there. ``MeasuredData.gaps()`` / ``gap_report()`` give the facts for a caller to print.
Time may be non-uniform (recorder jitter, dropped frames), but it must be finite and
strictly increasing: the readers settle repeated and late stamps first and say so
(:mod:`.timebase`), and :attr:`MeasuredData.timebase` says what the stamps are.
"""

from __future__ import annotations

import difflib
import functools
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..errors import DataError
from .timebase import Repairs, TimeBase, inspect, settle

class MaskedSamplesWarning(UserWarning):
    """A loaded file has missing samples; they are masked, not interpolated."""


class MissingColumn(DataError):
    """A requested column (or the time column) is not in the file.

    ``present`` lists the columns the file does have, so that a caller can re-raise the
    problem in its own terms (the experiment config names the key that asked for it).
    """

    def __init__(self, column: str, present: list[str], file: str | None = None,
                 skipped: Mapping[str, str] | None = None):
        self.column, self.present = column, list(present)
        self.skipped = dict(skipped or {})
        super().__init__(describe_missing(column, present, self.skipped), file)


def describe_missing(column: str, present: list[str],
                     skipped: Mapping[str, str] | None = None) -> str:
    """``no column 'x'; columns present: a, b (did you mean 'a'?)`` plus skipped ones."""
    listing = ", ".join(present) if present else "(none)"
    message = f"no column '{column}'; columns present: {listing}"
    close = close_matches(column, present)
    if close:
        message += " (did you mean " + " or ".join(f"'{c}'" for c in close) + "?)"
    if skipped and column in skipped:
        message += f"; '{column}' was not read: {skipped[column]}"
    elif skipped:
        message += "; not read: " + "; ".join(f"{k} ({v})" for k, v in skipped.items())
    return message


def close_matches(word: str, candidates: list[str], n: int = 3) -> list[str]:
    """Candidates that look like ``word``, ignoring case (difflib ratio >= 0.6)."""
    lowered: dict[str, str] = {}
    for c in candidates:
        lowered.setdefault(c.lower(), c)
    return [lowered[m] for m in difflib.get_close_matches(word.lower(), list(lowered), n=n, cutoff=0.6)]


@dataclass(frozen=True)
class Gap:
    """A run of consecutive masked samples of one column.

    ``start`` and ``end`` are the times of the first and last masked sample; the hole
    in the record reaches from the valid sample before ``start`` to the one after
    ``end``. ``first_row``/``last_row`` are spreadsheet rows for CSV files, else None.
    """

    column: str
    start: float
    end: float
    n_samples: int
    first_row: int | None = None
    last_row: int | None = None

    def __str__(self) -> str:
        rows = f", rows {self.first_row}-{self.last_row}" if self.first_row is not None else ""
        return (f"{self.column}: {self.n_samples} masked sample(s) from "
                f"{self.start:g} s to {self.end:g} s{rows}")


@dataclass(frozen=True, eq=False)
class MeasuredData:
    """One recording: a time base, columns with NaN where missing, and their masks.

    Arrays are stored read-only. ``rows`` holds the file row of each sample for CSV
    files (for messages), else None. ``notes`` says what reading skipped in the file
    besides stamps (a CSV's units row), so that it is never done silently. Build one
    from arrays with :meth:`from_arrays`.
    """

    source: str
    time: np.ndarray
    columns: dict[str, np.ndarray]
    valid: dict[str, np.ndarray]
    rows: np.ndarray | None = field(default=None, compare=False)
    repairs: Repairs = field(default=Repairs(), compare=False)  # what loading did to the stamps
    notes: tuple[str, ...] = field(default=(), compare=False)  # what reading skipped (a units row)
    units: Mapping[str, str] = field(default_factory=dict, compare=False)  # per column, as a units row states them

    def __post_init__(self):
        time = _readonly(np.asarray(self.time, dtype=np.float64))
        if time.ndim != 1 or time.size == 0:
            raise DataError("time must be a non-empty 1-D array", self.source)
        bad = first_bad_time(time)
        if bad is not None:
            raise DataError(f"sample {bad + 1}: {bad_time_reason(time, bad)}", self.source)
        if set(self.columns) != set(self.valid):
            raise DataError(f"columns and valid need the same keys (columns {sorted(self.columns)}, valid "
                            f"{sorted(self.valid)})", self.source)
        columns, valid = {}, {}
        for name, values in self.columns.items():
            values = np.asarray(values, dtype=np.float64)
            mask = np.asarray(self.valid[name], dtype=bool)
            if values.shape != time.shape or mask.shape != time.shape:
                raise DataError(f"column '{name}' has {values.size} samples and "
                                f"{mask.size} mask entries; time has {time.size}", self.source)
            if np.any(mask & ~np.isfinite(values)):
                raise DataError(f"column '{name}' is marked valid where it is not finite (sample "
                                f"{int(np.argmax(mask & ~np.isfinite(values))) + 1})", self.source)
            columns[name], valid[name] = _readonly(values), _readonly(mask)
        object.__setattr__(self, "time", time)
        object.__setattr__(self, "columns", columns)
        object.__setattr__(self, "valid", valid)
        if self.rows is not None:
            object.__setattr__(self, "rows", _readonly(np.asarray(self.rows, dtype=np.int64)))

    @classmethod
    def from_arrays(cls, time, columns: Mapping[str, np.ndarray],
                    source: str = "<arrays>") -> "MeasuredData":
        """Wrap arrays; non-finite values become NaN and are masked."""
        cols, valid = {}, {}
        for name, values in columns.items():
            values = np.array(values, dtype=np.float64)
            ok = np.isfinite(values)
            values[~ok] = np.nan
            cols[name], valid[name] = values, ok
        return cls(source, np.asarray(time, dtype=np.float64), cols, valid)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.columns)

    @functools.cached_property
    def timebase(self) -> TimeBase:
        """What the stamps are (step, jitter, missing frames) and how loading repaired them."""
        return inspect(self.time, self.source, self.repairs)

    def with_valid(self, valid: Mapping[str, np.ndarray]) -> "MeasuredData":
        """The same recording with some columns' masks replaced (samples flagged invalid).
        The values stay as recorded: what masked them (a config's flags and limits) masks
        them again when the recording is read back from an archive, which keeps values only."""
        masks = {k: np.asarray(valid.get(k, v), dtype=bool) & v for k, v in self.valid.items()}
        return MeasuredData(self.source, self.time, self.columns, masks, self.rows, self.repairs, self.notes,
                            self.units)

    def __len__(self) -> int:
        return self.time.size

    def n_valid(self, column: str) -> int:
        return int(np.count_nonzero(self._valid(column)))

    def window(self, t_start: float | None = None, t_end: float | None = None) -> "MeasuredData":
        """The samples with ``t_start <= time <= t_end`` (either end may be open)."""
        keep = np.ones(self.time.shape, dtype=bool)
        if t_start is not None:
            keep &= self.time >= t_start
        if t_end is not None:
            keep &= self.time <= t_end
        if not keep.any():
            raise DataError(f"no samples between {t_start} s and {t_end} s (the record spans "
                            f"{self.time[0]:g} s to {self.time[-1]:g} s)", self.source)
        idx = np.flatnonzero(keep)
        sl = slice(idx[0], idx[-1] + 1)  # time is increasing, so the kept samples are contiguous
        return MeasuredData(
            self.source, self.time[sl],
            {k: v[sl] for k, v in self.columns.items()},
            {k: v[sl] for k, v in self.valid.items()},
            None if self.rows is None else self.rows[sl], self.repairs, self.notes, self.units,
        )

    def resample(self, times) -> "MeasuredData":
        """The columns linearly interpolated onto ``times`` (inside the record): a common
        base for recordings made at other rates. A new sample is masked unless both
        samples around it are valid."""
        times = np.asarray(times, dtype=np.float64)
        tol = 1e-9 * max(1.0, abs(self.time[0]), abs(self.time[-1]))
        if times.size == 0 or times[0] < self.time[0] - tol or times[-1] > self.time[-1] + tol:
            raise DataError(f"a new time base must lie inside the record ({self.time[0]:g} s to "
                            f"{self.time[-1]:g} s)", self.source)
        t = np.clip(times, self.time[0], self.time[-1])
        lo = np.clip(np.searchsorted(self.time, t, side="right") - 1, 0, max(self.time.size - 2, 0))
        hi = np.minimum(lo + 1, self.time.size - 1)
        span = self.time[hi] - self.time[lo]
        w = np.divide(t - self.time[lo], span, out=np.zeros_like(t), where=span > 0)
        columns, valid = {}, {}
        for name, v in self.columns.items():
            ok = self.valid[name]
            inside = (ok[lo] & ok[hi]) | (ok[lo] & (w == 0)) | (ok[hi] & (w == 1))
            with np.errstate(invalid="ignore"):
                values = np.where(w == 1, v[hi], np.where(w == 0, v[lo], (1 - w) * v[lo] + w * v[hi]))
            columns[name] = np.where(inside, values, np.nan)
            valid[name] = inside & np.isfinite(columns[name])
        return MeasuredData(f"{self.source} (resampled)", times, columns, valid, notes=self.notes, units=self.units)

    def gaps(self, column: str | None = None) -> tuple[Gap, ...]:
        """Masked intervals of one column, or of every column when ``column`` is None."""
        names = self.names if column is None else (column,)
        found = []
        for name in names:
            masked = ~self._valid(name)
            edges = np.diff(np.concatenate(([0], masked.view(np.int8), [0])))
            for i, j in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
                rows = (None, None) if self.rows is None else (int(self.rows[i]), int(self.rows[j - 1]))
                found.append(Gap(name, float(self.time[i]), float(self.time[j - 1]), int(j - i), *rows))
        return tuple(found)

    def gap_report(self) -> str:
        """One line per gap, headed by the source; empty when nothing is masked."""
        gaps = self.gaps()
        if not gaps:
            return ""
        total = {}
        for g in gaps:
            total[g.column] = total.get(g.column, 0) + g.n_samples
        head = ", ".join(f"{n} in '{c}'" for c, n in total.items())
        lines = [f"{self.source}: masked samples ({head}) are left out of fits (in a model's input they are "
                 "bridged as its experiment allows, and said):"]
        lines += [f"  {g}" for g in gaps]
        return "\n".join(lines)

    def _valid(self, column: str) -> np.ndarray:
        if column not in self.valid:
            raise MissingColumn(column, list(self.names), self.source)
        return self.valid[column]


def from_recorded(time: np.ndarray, columns: dict[str, np.ndarray], source: str, time_column: str,
            rows: np.ndarray | None = None, notes: tuple[str, ...] = (),
            units: Mapping[str, str] | None = None) -> MeasuredData:
    """A reader's arrays -> :class:`MeasuredData`: stamps settled (:func:`.timebase.settle`),
    non-finite values masked; ``notes`` say what the reader skipped."""
    time, columns, rows, repairs = settle(time, columns, rows, source, time_column)
    cols, valid = {}, {}
    for name, v in columns.items():
        v = np.array(v, dtype=np.float64)
        ok = np.isfinite(v)
        v[~ok] = np.nan
        cols[name], valid[name] = v, ok
    return MeasuredData(source, time, cols, valid, rows, repairs, tuple(notes), dict(units or {}))


def first_bad_time(time: np.ndarray) -> int | None:
    """Index of the first non-finite or non-increasing time stamp, or None."""
    bad = np.flatnonzero(~np.isfinite(time))
    first = int(bad[0]) if bad.size else None
    with np.errstate(invalid="ignore"):
        step = np.flatnonzero(~(np.diff(time) > 0)) + 1
    step = step[np.isfinite(time[step]) & np.isfinite(time[step - 1])]
    if step.size and (first is None or step[0] < first):
        first = int(step[0])
    return first


def bad_time_reason(time: np.ndarray, i: int) -> str:
    if not np.isfinite(time[i]):
        return f"time is {time[i]} (missing or not finite); every sample needs a time"
    return (f"time {time[i]:g} s does not increase from the previous sample's "
            f"{time[i - 1]:g} s (time must be strictly increasing)")


def _readonly(a: np.ndarray) -> np.ndarray:
    """A read-only array; writeable input is copied so the caller's array stays theirs."""
    if a.flags.writeable:
        a = a.copy()
        a.flags.writeable = False
    return a


def sample_onto(t_sim, y_sim, t_meas) -> np.ndarray:
    """The simulation ``y_sim(t_sim)`` linearly interpolated at the measured times.

    ``t_sim`` must be non-decreasing: simulators repeat a time point at an event (the
    values just before and after it); at such a time the value after the event is
    taken. ``y_sim`` may be (n,) or (n, k). A measured time outside the simulated span
    (beyond a rounding tolerance) is a ``ValueError``: there is nothing to compare.
    """
    t_sim = np.asarray(t_sim, dtype=np.float64)
    y_sim = np.asarray(y_sim, dtype=np.float64)
    t_meas = np.asarray(t_meas, dtype=np.float64)
    if t_sim.ndim != 1 or t_sim.size < 2:
        raise ValueError("t_sim must be a 1-D array of at least two time points")
    if y_sim.shape[:1] != t_sim.shape or y_sim.ndim > 2:
        raise ValueError(f"y_sim has shape {y_sim.shape}; expected ({t_sim.size},) or ({t_sim.size}, k)")
    if np.any(np.diff(t_sim) < 0) or not np.all(np.isfinite(t_sim)):
        raise ValueError("t_sim must be finite and non-decreasing")
    if t_meas.size == 0:
        return np.empty((0,) + y_sim.shape[1:])
    lo, hi = t_sim[0], t_sim[-1]
    tol = 1e-9 * max(1.0, abs(lo), abs(hi))
    if t_meas.min() < lo - tol or t_meas.max() > hi + tol:
        raise ValueError(f"measured times {t_meas.min():g} s to {t_meas.max():g} s are not "
                         f"inside the simulated span {lo:g} s to {hi:g} s")
    t = np.clip(t_meas, lo, hi)
    i = np.clip(np.searchsorted(t_sim, t, side="right") - 1, 0, t_sim.size - 2)
    t0, t1 = t_sim[i], t_sim[i + 1]
    dt = t1 - t0
    w = np.divide(t - t0, dt, out=np.ones_like(t), where=dt > 0)
    if y_sim.ndim == 2:
        w = w[:, None]
    return (1.0 - w) * y_sim[i] + w * y_sim[i + 1]
