"""The time base of a recording as recorders write it: inspected on load, repaired only
where that is safe, and said.

Phasor data concentrators drop, repeat and delay frames; historians and disturbance
recorders write software time stamps with jitter and rounding (NASPI-2016-TR-002 /
PNNL-25262 on synchrophasor data quality). Everything downstream (the ROCOF's local fits,
the noise model's whitening, the input table) works on the stamps as recorded, so the
stamps are only repaired where the repair cannot change a value:

- a repeated stamp whose values agree (or where one copy is blank) is dropped, and said;
  a repeated stamp whose values disagree is an error naming both rows;
- a stamp earlier than the one before it by at most :data:`MAX_BACKSTEP` frames (a frame
  delivered late) is sorted into place, and said; a larger step back (a clock reset, two
  recordings joined) is an error naming the rows;
- nothing else is moved: jitter, rounding and dropped frames stay as recorded and are
  measured (:func:`inspect`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import DataError

MAX_BACKSTEP = 1.0  # frames: a later stamp may come before an earlier one by this much, no more
HOLE_FRAMES = 2  # missing frames in a row from which a hole is listed by its times
_LISTED = 5  # holes named by their times in a description


class TimeBaseWarning(UserWarning):
    """A recording's time stamps were repaired (repeats dropped, late frames sorted)."""


@dataclass(frozen=True)
class Repairs:
    """What loading did to the stamps: repeated stamps dropped, late ones sorted (counts
    and, for messages, the first rows affected)."""

    repeated: int = 0
    reordered: int = 0
    words: tuple[str, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.repeated or self.reordered)


@dataclass(frozen=True)
class TimeBase:
    """What the stamps of one recording are: the nominal step, the stamps' jitter about a
    grid of that step (a straight-line fit, so a clock running slightly fast is not
    jitter), frames missing from that grid, and the repairs made on load."""

    source: str
    samples: int
    step: float
    jitter_rms: float
    jitter_max: float
    dropped: int
    longest_drop: int
    holes: tuple[tuple[float, float, int], ...]  # (stamp before, stamp after, frames missing), >= HOLE_FRAMES
    repairs: Repairs = Repairs()

    @property
    def regular(self) -> bool:
        """Stamps on one grid to within 1 % of a step (rounding), no frame missing."""
        return self.dropped == 0 and self.jitter_max <= 0.01 * self.step

    def describe(self) -> str:
        """One line, as the CLI and the report print it."""
        clauses = [f"{self.samples} samples every {_ms(self.step)} ms ({1.0 / self.step:.4g} per second)",
                   "regular stamps (on one grid within 1 % of a step)" if self.jitter_max <= 0.01 * self.step else
                   f"jitter {_ms(self.jitter_rms)} ms RMS, {_ms(self.jitter_max)} ms at most"]
        if self.dropped:
            listed = ", ".join(f"{a:g}-{b:g} s ({n})" for a, b, n in self.holes[:_LISTED])
            more = f" and {len(self.holes) - _LISTED} more" if len(self.holes) > _LISTED else ""
            clauses.append(f"{self.dropped} frame(s) missing, at most {self.longest_drop} in a row"
                           + (f" (holes: {listed}{more})" if self.holes else ""))
        else:
            clauses.append("no frame missing")
        if self.repairs.repeated:
            clauses.append(f"{self.repairs.repeated} repeated stamp(s) dropped, their values agreeing")
        if self.repairs.reordered:
            clauses.append(f"{self.repairs.reordered} stamp(s) out of order, sorted")
        return "; ".join(clauses)

    def to_json(self) -> dict:
        return {"samples": self.samples, "step": self.step, "jitter_rms": self.jitter_rms,
                "jitter_max": self.jitter_max, "dropped": self.dropped, "longest_drop": self.longest_drop,
                "holes": [list(h) for h in self.holes], "repeated": self.repairs.repeated,
                "reordered": self.repairs.reordered, "regular": self.regular}


def _ms(seconds: float) -> str:
    return f"{1e3 * seconds:.3g}"


def frame_numbers(time: np.ndarray, step: float) -> np.ndarray:
    """Each stamp's frame on a grid of ``step`` from the first: a step of k frames (k >= 1,
    rounded) between neighbours, so jitter below half a step never moves a frame."""
    t = np.asarray(time, dtype=float)
    if t.size < 2:
        return np.zeros(t.size, dtype=np.int64)
    k = np.maximum(np.rint(np.diff(t) / step), 1).astype(np.int64)
    return np.concatenate([[0], np.cumsum(k)])


def nominal_step(time: np.ndarray) -> float:
    """The recorder's step: the median of the steps (a missing frame makes one step two; a
    repeated stamp makes none)."""
    steps = np.diff(np.asarray(time, dtype=float))
    steps = steps[steps > 0]
    return float(np.median(steps)) if steps.size else 1.0


def inspect(time: np.ndarray, source: str = "", repairs: Repairs = Repairs()) -> TimeBase:
    """The facts of a strictly increasing time base (see :class:`TimeBase`)."""
    t = np.asarray(time, dtype=float)
    step = nominal_step(t)
    k = frame_numbers(t, step)
    if t.size > 2:
        slope, intercept = np.polyfit(k.astype(float), t, 1)
        jitter = t - (intercept + slope * k)
        step = float(slope)
    else:
        jitter = np.zeros(t.size)
    missing = np.diff(k) - 1 if k.size > 1 else np.zeros(0, dtype=np.int64)
    where = np.flatnonzero(missing >= HOLE_FRAMES)
    holes = tuple((float(t[i]), float(t[i + 1]), int(missing[i])) for i in where)
    return TimeBase(source, int(t.size), step, float(np.sqrt(np.mean(jitter ** 2))) if t.size else 0.0,
                    float(np.max(np.abs(jitter))) if t.size else 0.0, int(missing.sum()),
                    int(missing.max()) if missing.size else 0, holes, repairs)


def settle(time: np.ndarray, columns: Mapping[str, np.ndarray], rows: np.ndarray | None, source: str,
           time_name: str = "time") -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray | None, Repairs]:
    """Stamps as recorded -> strictly increasing stamps, by the safe repairs of the module
    docstring, in their order: every stamp a number, late frames sorted into place,
    repeated frames merged. ``rows`` (file rows, for messages; None: 1-based sample
    numbers) follow their samples. Raises :class:`DataError` naming rows where no repair
    is safe."""
    samples = _Samples(np.asarray(time, dtype=float), {k: np.asarray(v, dtype=float) for k, v in columns.items()},
                       None if rows is None else np.asarray(rows), np.arange(1, len(time) + 1), source, time_name)
    samples.check_finite()
    samples, reordered, sorted_words = _sorted(samples)
    samples, repeated, merged_words = _merged(samples)
    return samples.t, samples.cols, samples.rows, Repairs(repeated, reordered, sorted_words + merged_words)


@dataclass(frozen=True, eq=False)
class _Samples:
    """Stamps and their columns as the repairs leave them, each sample still naming where
    it came from in the file (its row, else its sample number) for the messages."""

    t: np.ndarray
    cols: dict[str, np.ndarray]
    rows: np.ndarray | None
    numbers: np.ndarray  # 1-based sample numbers in the file
    source: str
    time_name: str

    @property
    def what(self) -> str:
        return "row" if self.rows is not None else "sample"

    def label(self, i: int) -> int:
        return int(self.rows[i]) if self.rows is not None else int(self.numbers[i])

    def line(self, i: int) -> int | None:
        """The file line a :class:`DataError` names (sample numbers are not lines)."""
        return self.label(i) if self.rows is not None else None

    def taking(self, index: np.ndarray) -> "_Samples":
        return _Samples(self.t[index], {k: v[index] for k, v in self.cols.items()},
                        None if self.rows is None else self.rows[index], self.numbers[index], self.source,
                        self.time_name)

    def check_finite(self) -> None:
        bad = np.flatnonzero(~np.isfinite(self.t))
        if bad.size:
            raise DataError(f"column '{self.time_name}': time is {self.t[bad[0]]} at {self.what} {self.label(bad[0])} "
                            "(missing or not finite); every sample needs a time", self.source, self.line(bad[0]))


def _sorted(s: _Samples) -> tuple[_Samples, int, tuple[str, ...]]:
    """Late frames sorted into place; a stamp further back than a late frame can be (a
    clock reset, two recordings joined) is a :class:`DataError`."""
    t = s.t
    back = np.flatnonzero(np.diff(t) < 0)
    if not back.size:
        return s, 0, ()
    step = nominal_step(np.sort(t))
    latest = np.maximum.accumulate(t)  # how far each stamp lies before the latest stamp seen so far
    behind = latest - t
    if behind.max() > MAX_BACKSTEP * step * (1 + 1e-6):
        first = int(np.flatnonzero(behind > MAX_BACKSTEP * step * (1 + 1e-6))[0])
        earlier = int(np.flatnonzero(t[:first] == latest[first])[0])
        raise DataError(f"column '{s.time_name}': time goes back from {latest[first]:g} s ({s.what} "
                        f"{s.label(earlier)}) to {t[first]:g} s ({s.what} {s.label(first)}), "
                        f"{behind[first] / step:.3g} frames of {_ms(step)} ms; a late frame may come at most "
                        f"{MAX_BACKSTEP:g} frame early, so this looks like a clock reset or two recordings joined: "
                        "split the file or fix its time column", s.source, s.line(first))
    reordered = int(np.count_nonzero(t[:-1] > t[1:]))
    first = int(back[0]) + 1
    words = (f"{reordered} stamp(s) out of order sorted into place (first at {s.what} {s.label(first)}, "
             f"{t[first]:g} s after {t[first - 1]:g} s)",)
    return s.taking(np.argsort(t, kind="stable")), reordered, words


def _merged(s: _Samples) -> tuple[_Samples, int, tuple[str, ...]]:
    """A run of equal stamps merged into its first sample, a value missing there taken
    from a copy; copies that disagree are a :class:`DataError` (which one the recorder
    meant cannot be told)."""
    t = s.t
    same = np.flatnonzero(np.diff(t) == 0)
    if not same.size:
        return s, 0, ()
    drop = np.zeros(t.size, dtype=bool)
    for i in same:  # once per repeated stamp, a few in a recording: not an inner loop
        j = i + 1
        head = i
        while head > 0 and t[head - 1] == t[i]:
            head -= 1
        for name, v in s.cols.items():
            a, b = v[head], v[j]
            if np.isfinite(a) and np.isfinite(b) and a != b:
                raise DataError(f"column '{name}': time {t[j]:g} s is written twice ({s.what}s {s.label(head)} and "
                                f"{s.label(j)}) with different values ({a:g} and {b:g}); which one the recorder "
                                "meant cannot be told: remove one of them", s.source, s.line(j))
            if not np.isfinite(a) and np.isfinite(b):
                v[head] = b
        drop[j] = True
    repeated = int(drop.sum())
    first = int(same[0]) + 1
    words = (f"{repeated} repeated stamp(s) dropped, their values agreeing with the first copy (first at "
             f"{s.what} {s.label(first)}, {t[first]:g} s)",)
    return s.taking(~drop), repeated, words


def check_step(base: TimeBase, limit: float, time_name: str = "time") -> None:
    """A step longer than ``limit`` seconds is no recording of dynamics this tool can use:
    most likely the time column is in another unit (milliseconds read as seconds)."""
    if base.step > limit:
        raise DataError(f"column '{time_name}' steps by {base.step:g} per sample, slower than any recording of "
                        f"governor dynamics (allowed: at most {limit:g} s); if the time is in milliseconds or "
                        "microseconds, say so: [data] time_unit = \"ms\" (or \"us\")", base.source)


def frames_between(base: TimeBase, t0: float, t1: float) -> float:
    """How many frames of the nominal step lie between two times (for messages)."""
    return (t1 - t0) / base.step if base.step > 0 else math.inf
