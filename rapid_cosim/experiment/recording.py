"""A recording as recorders write it, read against its config: quality flags, values no
recorder of the quantity can mean, gaps in an input, and what was done about each.

Nothing is repaired silently. What :mod:`rapid_cosim.data.timebase` did to the stamps on
load, and everything here, ends in one :class:`Recording` that the CLI prints, the
validation report shows and the JSON carries. The config keys::

    [data]
    time_unit = "ms"                              # a time column in ms or us (default s)
    flags = { column = "STAT", kind = "c37.118" } # or kind = "valid" (1 valid, 0 not)
    limits = { frequency = 5.0, rocof = 20.0, power = 2.0, power_step = 0.5 }
    [inputs]
    f_dev = { column = "FREQ", ..., gaps = { max = 2.0, fill = "linear" } }

- A C37.118 STAT word marks a frame invalid by bits 15-14 (data error) or bit 13 (sync
  lost, IEEE C37.118.2-2011 table 7); a ``valid`` column by 0. Every column of the file is
  masked there, as blank samples are: out of the fit and out of the ROCOF's windows.
- Limits (defaults above; ``false`` turns one off): a frequency (an input converted from
  Hz about its nominal) outside nominal +- ``frequency`` Hz, or a one- or two-frame spike
  steeper than ``rocof`` Hz/s out and back; a power with a rating beyond +-``power`` x the
  rating, or a spike of more than ``power_step`` x the rating per frame out and back. Such
  samples are masked with a warning naming rows. A persistent jump is left alone: which
  side of it is wrong cannot be told.
- An input's masked or missing samples are bridged by linear interpolation, never fed to
  the model: up to :data:`SHORT_GAP` seconds without a word of config (a dropped frame, a
  burst of five), longer only up to ``gaps.max``; then the outputs in the gap and for
  ``max(window, gap)`` after it (the governor's memory of the filled input) are left out
  of the fit. A longer gap is an error naming the column and times.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..data import MeasuredData
from ..data.timebase import TimeBase
from ..errors import ConfigError
from .schema import DATA_FLAGS, DATA_LIMITS, GAPS
from .toml_writer import config_key

FLAG_KINDS = ("c37.118", "valid")
STAT_INVALID = 0xE000  # C37.118 STAT bits 15-14 (data error) and 13 (PMU sync lost)
LIMITS = {"frequency": 5.0, "rocof": 20.0, "power": 2.0, "power_step": 0.5}
LIMIT_UNITS = {"frequency": "Hz about nominal", "rocof": "Hz/s", "power": "x rating", "power_step": "x rating per frame"}
SHORT_GAP = 0.25  # s: an input hole bridged without being asked
MAX_STEP = 1.0  # s: no recording of governor dynamics samples slower
GAP_KEYS = GAPS.names
FILLS = ("linear",)
FREQUENCY_UNITS = {"Hz": 1.0, "mHz": 1e-3, "kHz": 1e3, "": 1.0}
_LISTED = 5
ALL = "*"  # a mask of every column (a frame flagged invalid)


class RecordingWarning(UserWarning):
    """Samples of a recording masked for a reason its config gives (flags, limits)."""


@dataclass(frozen=True)
class Masked:
    """Samples of one column masked for one reason."""

    column: str
    reason: str
    count: int
    where: str  # the first rows or times, for the reader

    def describe(self) -> str:
        what = "frame(s), every column," if self.column == ALL else f"sample(s) of '{self.column}'"
        return f"{self.count} {what} masked: {self.reason} ({self.where})"


@dataclass(frozen=True)
class Bridge:
    """A hole in an input bridged by interpolation: the valid stamps either side, the
    time with no valid sample, and the span of outputs left out of the fit (if any)."""

    column: str
    before: float
    after: float
    seconds: float
    excluded: tuple[float, float] | None = None


@dataclass(frozen=True)
class Recording:
    """What a recording was found to be and what was done about it (module docstring)."""

    timebases: dict[str, TimeBase] = field(default_factory=dict)  # per file
    blanks: tuple[Masked, ...] = ()  # blank or non-finite samples of the columns used, as read
    masked: tuple[Masked, ...] = ()
    bridges: tuple[Bridge, ...] = ()
    unfit: tuple[tuple[float, float, int], ...] = ()  # ROCOF windows with no fit: outputs left out
    notes: tuple[str, ...] = ()  # what reading the files did (a units row under the header skipped)

    def lines(self) -> list[str]:
        """One line per fact, as the CLI and the report print them."""
        out = [f"time base of {name}: {base.describe()}" for name, base in self.timebases.items()]
        out += list(self.notes)
        out += [m.describe() for m in (*self.blanks, *self.masked)]
        by_column: dict[str, list[Bridge]] = {}
        for b in self.bridges:
            by_column.setdefault(b.column, []).append(b)
        for column, bridges in by_column.items():
            longest = max(b.seconds for b in bridges)
            listed = ", ".join(f"{b.before:g}-{b.after:g} s" for b in bridges[:_LISTED])
            more = f" and {len(bridges) - _LISTED} more" if len(bridges) > _LISTED else ""
            clauses = [f"input '{column}': {len(bridges)} hole(s) bridged by linear interpolation, the longest "
                       f"{longest:.3g} s ({listed}{more})"]
            left = [b.excluded for b in bridges if b.excluded]
            if left:
                clauses.append("outputs left out of the fit over " + ", ".join(f"{a:g}-{z:g} s" for a, z in left))
            out.append("; ".join(clauses))
        if self.unfit:
            spans = ", ".join(f"{a:g}-{b:g} s ({n})" for a, b, n in self.unfit[:_LISTED])
            out.append(f"ROCOF: {sum(n for *_, n in self.unfit)} sample(s) whose window could not hold a fit "
                       f"({spans}); their power samples are left out of the fit")
        return out

    @property
    def plain(self) -> bool:
        """Regular stamps, nothing repaired, masked, bridged or left without a ROCOF fit."""
        return (all(b.regular and not b.repairs for b in self.timebases.values())
                and not (self.blanks or self.masked or self.bridges or self.unfit or self.notes))

    def summary(self) -> dict:
        """:meth:`to_json` with the words and whether the recording is plain."""
        return {**self.to_json(), "plain": self.plain, "lines": self.lines()}

    def to_json(self) -> dict:
        return {"timebase": {k: b.to_json() for k, b in self.timebases.items()},
                "masked": [{"column": m.column, "reason": m.reason, "count": m.count, "where": m.where}
                           for m in (*self.blanks, *self.masked)],
                "bridged": [{"column": b.column, "before": b.before, "after": b.after, "seconds": b.seconds,
                             "excluded": list(b.excluded) if b.excluded else None} for b in self.bridges],
                "rocof_unfit": [list(u) for u in self.unfit], "notes": list(self.notes)}


@dataclass(frozen=True)
class RecordingSpec:
    """The ``[data]`` keys of this module, read."""

    flags: tuple[str, str] | None = None  # (column, kind)
    limits: dict[str, float | None] = field(default_factory=lambda: dict(LIMITS))


def read_spec(d: dict, cfg) -> RecordingSpec:
    flags = None
    if "flags" in d:
        spec = cfg.table(d["flags"], "data.flags")
        cfg.check_keys(spec, DATA_FLAGS.names, "data.flags")
        kind = cfg.string(spec, "data.flags", "kind", default="c37.118")
        if kind not in FLAG_KINDS:
            raise ConfigError(f"kind {kind!r} is not one of {', '.join(FLAG_KINDS)}", cfg.file, "data.flags.kind")
        flags = (cfg.string(spec, "data.flags", "column"), kind)
    limits: dict[str, float | None] = dict(LIMITS)
    if "limits" in d:
        table = cfg.table(d["limits"], "data.limits")
        cfg.check_keys(table, DATA_LIMITS.names, "data.limits")
        for k, v in table.items():
            if v is False:
                limits[k] = None
                continue
            value = cfg.number(v, f"data.limits.{k}")
            if not value > 0:
                raise ConfigError(f"{k} must be > 0 ({LIMIT_UNITS[k]}), or false to turn the check off; got "
                                  f"{value:g}", cfg.file, f"data.limits.{k}")
            limits[k] = value
    return RecordingSpec(flags, limits)


def read_gaps(spec: dict, cfg, key: str) -> float:
    """An input's ``gaps`` table -> the longest hole it may bridge (s)."""
    if "gaps" not in spec:
        return SHORT_GAP
    table = cfg.table(spec["gaps"], f"{key}.gaps")
    cfg.check_keys(table, GAP_KEYS, f"{key}.gaps")
    fill = cfg.string(table, f"{key}.gaps", "fill", default="linear")
    if fill not in FILLS:
        raise ConfigError(f"fill {fill!r} is not one of {', '.join(FILLS)}", cfg.file, f"{key}.gaps.fill")
    longest = cfg.number(cfg.require(table, f"{key}.gaps", "max"), f"{key}.gaps.max")
    if not 0 < longest <= 60.0:
        raise ConfigError(f"max must be in (0, 60] s, got {longest:g}", cfg.file, f"{key}.gaps.max")
    return max(longest, SHORT_GAP)


def check_step(data: MeasuredData, cfg, key: str) -> None:
    """A step longer than MAX_STEP is a time column in another unit (ms read as s)."""
    base = data.timebase
    if base.step > MAX_STEP:
        raise ConfigError(f"{data.source}: the time column steps by {base.step:g} per sample, slower than any "
                          f"recording of governor dynamics (allowed: at most {MAX_STEP:g} s); if it is in "
                          "milliseconds or microseconds, say so: [data] time_unit = \"ms\" (or \"us\")", cfg.file, key)


def _where(data: MeasuredData, idx: np.ndarray) -> str:
    idx = np.asarray(idx)
    head = idx[:_LISTED]
    if data.rows is not None:
        words = "rows " + ", ".join(str(int(data.rows[i])) for i in head)
    else:
        words = "at " + ", ".join(f"{data.time[i]:g} s" for i in head)
    return words + (f" and {idx.size - head.size} more" if idx.size > head.size else "")


def blanks(data: MeasuredData, columns) -> list[Masked]:
    """The blank (or non-finite) samples of ``columns`` as read: masked by the reader."""
    out = []
    for column in dict.fromkeys(columns):
        if column in data.columns and not data.valid[column].all():
            idx = np.flatnonzero(~data.valid[column])
            gaps = data.gaps(column)
            longest = max(gaps, key=lambda g: g.n_samples)
            out.append(Masked(column, f"blank or not a number as recorded; the longest run {longest.n_samples} "
                                      f"from {longest.start:g} s to {longest.end:g} s", int(idx.size),
                              _where(data, idx)))
    return out


def apply_flags(data: MeasuredData, spec: RecordingSpec, cfg) -> tuple[MeasuredData, list[Masked]]:
    """Every column masked where the quality column marks a frame invalid."""
    if spec.flags is None:
        return data, []
    column, kind = spec.flags
    key = "data.flags.column"
    if column not in data.columns:
        from ..data import describe_missing
        raise ConfigError(f"{data.source}: {describe_missing(column, list(data.names))}", cfg.file, key)
    raw = data.columns[column]
    finite = np.isfinite(raw)
    if kind == "c37.118":
        bad = np.flatnonzero(finite & ((raw != np.round(raw)) | (raw < 0) | (raw > 0xFFFF)))
        if bad.size:
            raise ConfigError(f"{data.source}: column '{column}' is not a C37.118 STAT word (an integer 0 to 65535) "
                              f"at {_where(data, bad)}: {raw[bad[0]]:g}", cfg.file, key)
        invalid = ~finite | ((np.where(finite, raw, 0).astype(np.int64) & STAT_INVALID) != 0)
        reason = f"the C37.118 STAT word '{column}' marks the frame invalid (data error or sync lost)"
    else:
        bad = np.flatnonzero(finite & (raw != 0) & (raw != 1))
        if bad.size:
            raise ConfigError(f"{data.source}: column '{column}' is not a validity flag (1 valid, 0 invalid) at "
                              f"{_where(data, bad)}: {raw[bad[0]]:g}", cfg.file, key)
        invalid = ~finite | (raw == 0)
        reason = f"'{column}' marks the frame invalid"
    if not invalid.any():
        return data, []
    if invalid.all():
        raise ConfigError(f"{data.source}: column '{column}' marks every sample invalid; nothing is left to fit",
                          cfg.file, key)
    masks = {c: data.valid[c] & ~invalid for c in data.names if c != column}
    hit = int(invalid.sum())
    note = Masked(ALL, reason, hit, _where(data, np.flatnonzero(invalid)))
    warnings.warn(f"{data.source}: {note.describe()}", RecordingWarning, stacklevel=3)
    return data.with_valid(masks), [note]


def _spikes(t: np.ndarray, v: np.ndarray, ok: np.ndarray, limit: float, per_second: bool) -> np.ndarray:
    """Valid samples that leave both neighbours (or a pair that leaves theirs) by more than
    ``limit`` (per second, or per frame), out one way and back the other."""
    idx = np.flatnonzero(ok)
    if idx.size < 3:
        return np.zeros(0, dtype=np.int64)
    tv, vv = t[idx], v[idx]
    step = np.diff(vv) / (np.diff(tv) if per_second else 1.0)
    big = np.abs(step) > limit
    out = set()
    for k in np.flatnonzero(big[:-1] & big[1:] & (np.sign(step[:-1]) != np.sign(step[1:]))):
        out.add(int(idx[k + 1]))
    for k in np.flatnonzero(big[:-2] & big[2:] & (np.sign(step[:-2]) != np.sign(step[2:])) & ~big[1:-1]):
        out.update((int(idx[k + 1]), int(idx[k + 2])))
    return np.array(sorted(out), dtype=np.int64)


def apply_limits(data: MeasuredData, spec: RecordingSpec, frequencies: dict[str, float],
                 powers: dict[str, float]) -> tuple[MeasuredData, list[Masked]]:
    """Samples no recorder of the quantity can mean, masked: ``frequencies`` maps a column
    to (its unit factor to Hz, nominal Hz), ``powers`` a column to its rating in the
    column's unit."""
    lim = spec.limits
    masks: dict[str, np.ndarray] = {}
    notes = []

    def mask(column: str, idx: np.ndarray, reason: str) -> None:
        if idx.size:
            masks[column] = masks.get(column, data.valid[column]).copy()
            masks[column][idx] = False
            notes.append(Masked(column, reason, int(idx.size), _where(data, idx)))

    for column, (factor, nominal) in frequencies.items():
        if column not in data.columns:
            continue
        v = data.columns[column] * factor
        ok = data.valid[column]
        if lim["frequency"] is not None:
            mask(column, np.flatnonzero(ok & (np.abs(v - nominal) > lim["frequency"])),
                 f"outside {nominal:g} +- {lim['frequency']:g} Hz")
        if lim["rocof"] is not None:
            ok = masks.get(column, ok)
            mask(column, _spikes(data.time, v, ok, lim["rocof"], True),
                 f"a one- or two-frame spike steeper than {lim['rocof']:g} Hz/s")
    for column, rating in powers.items():
        if column not in data.columns:
            continue
        v, ok = data.columns[column], data.valid[column]
        if lim["power"] is not None:
            mask(column, np.flatnonzero(ok & (np.abs(v) > lim["power"] * rating)),
                 f"beyond +-{lim['power']:g} x the rating ({rating:g})")
        if lim["power_step"] is not None:
            ok = masks.get(column, ok)
            mask(column, _spikes(data.time, v, ok, lim["power_step"] * rating, False),
                 f"a one- or two-frame spike of more than {lim['power_step']:g} x the rating per frame")
    for note in notes:
        warnings.warn(f"{data.source}: {note.describe()}", RecordingWarning, stacklevel=3)
    return (data.with_valid(masks) if masks else data), notes


def bridges(name: str, column: str, source: MeasuredData, start: float, stop: float, longest: float, cfg,
            window: float) -> list[Bridge]:
    """The holes of input ``name`` (its ``column``) inside the simulated span, each
    bridged or refused."""
    key = config_key("inputs", name)
    t = source.time
    ok = source.valid[column]
    step = source.timebase.step
    tv = t[ok]
    if tv.size == 0:
        raise ConfigError(f"column '{column}' has no valid sample: every value is blank or masked", cfg.file, key)
    if tv[0] > start + step + SHORT_GAP or tv[-1] < stop - step - SHORT_GAP:
        raise ConfigError(f"column '{column}' has valid values from {tv[0]:g} s to {tv[-1]:g} s, the simulation runs "
                          f"{start:g} s to {stop:g} s: an input must cover it", cfg.file, key)
    inside = (tv >= start - step) & (tv <= stop + step)
    first = max(int(np.argmax(inside)) - 1, 0)
    last = min(int(tv.size - 1 - np.argmax(inside[::-1])) + 1, tv.size - 1)
    tv = tv[first:last + 1]
    span = np.diff(tv) - step
    out = []
    for k in np.flatnonzero(np.diff(tv) > 1.5 * step):
        seconds = float(span[k])
        if seconds > longest + 1e-6:  # stamps' rounding
            hint = (f"; to bridge it, add gaps = {{ max = {np.ceil(seconds * 10 - 1e-6) / 10:g}, fill = \"linear\" }} to "
                    f"[{key}] (the outputs in and near it then leave the fit)") if longest <= SHORT_GAP \
                else f" (its gaps.max is {longest:g} s)"
            raise ConfigError(f"column '{column}' has no valid sample between {tv[k]:g} s and {tv[k + 1]:g} s "
                              f"({seconds:.3g} s): a gap in an input longer than {longest:g} s cannot be run "
                              f"through{hint}", cfg.file, key)
        excluded = None
        if seconds > SHORT_GAP + 1e-6:
            excluded = (float(tv[k] - window / 2), float(tv[k + 1] + max(window, seconds)))
        out.append(Bridge(column, float(tv[k]), float(tv[k + 1]), seconds, excluded))
    return out


def exclude(data: MeasuredData, columns, spans) -> MeasuredData:
    """``data`` with the output ``columns`` masked over ``spans``."""
    spans = list(spans)
    if not spans:
        return data
    hit = np.zeros(data.time.size, dtype=bool)
    for a, b in spans:
        hit |= (data.time >= a) & (data.time <= b)
    return data.with_valid({c: data.valid[c] & ~hit for c in columns if c in data.columns})
