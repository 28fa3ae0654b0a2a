"""Measurements in, masked and on a time base.

A recording becomes a :class:`MeasuredData`: one strictly increasing ``time`` vector and
one float64 array per column, with NaN where a sample is missing and a boolean ``valid``
mask beside it. Missing samples are *masked*, never interpolated over: a fit simply has
fewer samples there. :func:`load_measurements` warns (:class:`MaskedSamplesWarning`)
when a file has masked samples, and ``MeasuredData.gaps()`` / ``gap_report()`` give the
same facts for a caller to print.

Formats, chosen by the file suffix:

``.csv``
    A header row of column names, then one sample per row, comma separated. An empty
    cell or ``nan`` is a missing sample (so is ``inf``: a recorder overflow is no
    reading). Any other text that is not a number is a :class:`DataError`.
``.mat``
    As RaPId stores them: a ``time`` vector and a ``signal`` array, one column per
    output. A 1-D ``signal`` (or one column) becomes column ``signal``; k columns become
    ``signal_0`` .. ``signal_<k-1>``. Any other numeric variable of the same length is
    a column too, named the same way. MAT v7.3 files are HDF5 and are read with h5py
    (MATLAB stores arrays transposed there; the orientation is found from the length of
    ``time``).
``.h5`` / ``.hdf5`` / ``.hdf``
    A ``time`` dataset and one dataset per column (a 2-D (N, k) dataset is split like
    ``signal``), in the root group or in the group named after a colon:
    ``run.h5:/tests/test1``.

Rows in error messages are counted as a spreadsheet shows them: the header is row 1,
the first sample row 2. For MAT and HDF5 files, errors name the 1-based sample number.

Time may be non-uniform (recorder jitter), but it must be finite and strictly
increasing; a repeated or decreasing time stamp is rejected at the row where it occurs.
"""

from __future__ import annotations

import csv
import difflib
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from rapid_cosim.errors import DataError

CSV_SUFFIXES = (".csv",)
MAT_SUFFIXES = (".mat",)
HDF5_SUFFIXES = (".h5", ".hdf5", ".hdf")

# Fewer pre-step samples than this give a noise level not worth reporting.
MIN_NOISE_SAMPLES = 10


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
    files (for messages), else None. Build one from arrays with :meth:`from_arrays`.
    """

    source: str
    time: np.ndarray
    columns: dict[str, np.ndarray]
    valid: dict[str, np.ndarray]
    rows: np.ndarray | None = field(default=None, compare=False)

    def __post_init__(self):
        time = _readonly(np.asarray(self.time, dtype=np.float64))
        if time.ndim != 1 or time.size == 0:
            raise DataError("time must be a non-empty 1-D array", self.source)
        bad = _first_bad_time(time)
        if bad is not None:
            raise DataError(f"sample {bad + 1}: {_bad_time_reason(time, bad)}", self.source)
        if set(self.columns) != set(self.valid):
            raise ValueError("columns and valid need the same keys")
        columns, valid = {}, {}
        for name, values in self.columns.items():
            values = np.asarray(values, dtype=np.float64)
            mask = np.asarray(self.valid[name], dtype=bool)
            if values.shape != time.shape or mask.shape != time.shape:
                raise DataError(f"column '{name}' has {values.size} samples and "
                                f"{mask.size} mask entries; time has {time.size}", self.source)
            if np.any(mask & ~np.isfinite(values)):
                raise ValueError(f"column '{name}' is marked valid where it is not finite")
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
            None if self.rows is None else self.rows[sl],
        )

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
        lines = [f"{self.source}: masked samples ({head}) are left out of fits, not interpolated:"]
        lines += [f"  {g}" for g in gaps]
        return "\n".join(lines)

    def _valid(self, column: str) -> np.ndarray:
        if column not in self.valid:
            raise MissingColumn(column, list(self.names), self.source)
        return self.valid[column]


# --------------------------------------------------------------------------- loading

def split_hdf5_path(path: str | Path) -> tuple[Path, str]:
    """``'run.h5:/a/b'`` -> ``(Path('run.h5'), '/a/b')``; no group -> ``'/'``."""
    text = str(path)
    m = re.match(r"^(.*\.(?:h5|hdf5|hdf|mat)):(/.*)$", text, flags=re.IGNORECASE)
    if m:
        return Path(m.group(1)), m.group(2)
    return Path(text), "/"


def load_measurements(path: str | Path, time_column: str = "time",
                      columns: Mapping[str, str] | None = None,
                      warn: bool = True) -> MeasuredData:
    """Read a recording (CSV, MAT or HDF5, by suffix) into a :class:`MeasuredData`.

    ``columns`` maps the names wanted to the names in the file (``{"pm": "signal_0"}``);
    when given, only those columns are kept, and a missing one is a
    :class:`MissingColumn` error listing what the file has. With ``warn`` a
    :class:`MaskedSamplesWarning` reports masked samples.
    """
    file, group = split_hdf5_path(path)
    suffix = file.suffix.lower()
    if group != "/" and suffix not in HDF5_SUFFIXES:
        raise DataError(f"a group ({group}) can only be given for HDF5 files", str(path))
    if not file.is_file():
        raise DataError(f"file not found: {file.resolve()}", str(file))
    source = str(path)
    if suffix in CSV_SUFFIXES:
        data = _read_csv(file, source, time_column)
        skipped: dict[str, str] = {}
    elif suffix in MAT_SUFFIXES:
        data, skipped = _read_mat(file, source, time_column)
    elif suffix in HDF5_SUFFIXES:
        data, skipped = _read_hdf5(file, group, source, time_column)
    else:
        supported = ", ".join(CSV_SUFFIXES + MAT_SUFFIXES + HDF5_SUFFIXES)
        raise DataError(f"unknown file type '{file.suffix}'; supported: {supported}", source)
    if columns is not None:
        for stored in columns.values():
            if stored not in data.columns:
                raise MissingColumn(stored, list(data.names), source, skipped)
        data = MeasuredData(source, data.time,
                            {new: data.columns[old] for new, old in columns.items()},
                            {new: data.valid[old] for new, old in columns.items()}, data.rows)
    if warn and data.gaps():
        warnings.warn(data.gap_report(), MaskedSamplesWarning, stacklevel=2)
    return data


def _read_csv(file: Path, source: str, time_column: str) -> MeasuredData:
    with open(file, newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        while header == []:  # leading blank lines
            header = next(reader, None)
        if header is None:
            raise DataError("the file is empty", source)
        names = [h.strip() for h in header]
        header_row = reader.line_num
        for k, name in enumerate(names):
            if not name:
                raise DataError(f"column {k + 1} of the header has no name", source, header_row)
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise DataError(f"repeated column name(s) in the header: {', '.join(dupes)}",
                            source, header_row)
        if time_column not in names:
            raise MissingColumn(time_column, [n for n in names if n != time_column], source)
        values: list[list[float]] = []
        rows: list[int] = []
        for record in reader:
            if not record or all(not c.strip() for c in record) and len(record) == 1:
                continue  # a blank line carries no sample
            row = reader.line_num
            if len(record) != len(names):
                raise DataError(f"expected {len(names)} fields ({', '.join(names)}), "
                                f"found {len(record)}: {','.join(record)!r}", source, row)
            parsed = []
            for name, cell in zip(names, record):
                text = cell.strip()
                if not text:
                    parsed.append(np.nan)
                    continue
                try:
                    parsed.append(float(text))
                except ValueError:
                    raise DataError(f"column '{name}': '{text}' is not a number "
                                    f"(leave the cell empty or write nan for a missing sample)",
                                    source, row) from None
            values.append(parsed)
            rows.append(row)
    if not values:
        raise DataError("the file has a header but no samples", source)
    table = np.array(values, dtype=np.float64)
    t_index = names.index(time_column)
    time = table[:, t_index]
    bad = _first_bad_time(time)
    if bad is not None:
        raise DataError(f"column '{time_column}': {_bad_time_reason(time, bad)}", source, rows[bad])
    cols, valid = {}, {}
    for k, name in enumerate(names):
        if k == t_index:
            continue
        v = table[:, k].copy()
        ok = np.isfinite(v)
        v[~ok] = np.nan
        cols[name], valid[name] = v, ok
    return MeasuredData(source, time, cols, valid, np.asarray(rows))


def _read_mat(file: Path, source: str, time_column: str) -> tuple[MeasuredData, dict[str, str]]:
    import h5py

    if h5py.is_hdf5(file):  # MAT v7.3
        with h5py.File(file, "r") as f:
            arrays = {k: np.asarray(f[k]) for k, obj in f.items()
                      if isinstance(obj, h5py.Dataset) and not k.startswith("#")
                      and _attr_str(obj.attrs.get("MATLAB_class")) not in ("char", "cell", "struct")}
        return _from_arrays(arrays, source, time_column, transposed=True)
    import scipy.io

    try:
        raw = scipy.io.loadmat(str(file))
    except (ValueError, TypeError, NotImplementedError) as e:
        raise DataError(f"cannot read MAT file: {e}", source) from None
    arrays = {k: v for k, v in raw.items() if not k.startswith("__") and isinstance(v, np.ndarray)}
    return _from_arrays(arrays, source, time_column, transposed=False)


def _read_hdf5(file: Path, group: str, source: str,
               time_column: str) -> tuple[MeasuredData, dict[str, str]]:
    import h5py

    with h5py.File(file, "r") as f:
        if group not in f or not isinstance(f[group], h5py.Group):
            groups: list[str] = []
            f.visititems(lambda name, obj: groups.append("/" + name)
                         if isinstance(obj, h5py.Group) else None)
            raise DataError(f"no group '{group}'; groups present: {', '.join(['/'] + groups)}", source)
        g = f[group]
        arrays = {k: np.asarray(obj) for k, obj in g.items() if isinstance(obj, h5py.Dataset)}
    return _from_arrays(arrays, source, time_column, transposed=False)


def _from_arrays(arrays: dict[str, np.ndarray], source: str, time_column: str,
                 transposed: bool) -> tuple[MeasuredData, dict[str, str]]:
    """Columns from named arrays that share the length of ``time``; the rest are skipped
    with a reason (so that asking for one of them says why it is not there)."""
    numeric = {k: v for k, v in arrays.items()
               if v.dtype.kind in "biuf" and v.size > 0}
    if time_column not in numeric:
        raise MissingColumn(time_column, sorted(k for k in arrays if k != time_column), source)
    time = numeric[time_column]
    if time.ndim > 2 or (time.ndim == 2 and min(time.shape) != 1):
        raise DataError(f"'{time_column}' must be a vector, it has shape {time.shape}", source)
    time = time.astype(np.float64).ravel()
    bad = _first_bad_time(time)
    if bad is not None:
        raise DataError(f"'{time_column}', sample {bad + 1}: {_bad_time_reason(time, bad)}", source)
    n = time.size
    cols: dict[str, np.ndarray] = {}
    skipped = {k: f"not numeric ({v.dtype})" for k, v in arrays.items()
               if k not in numeric and k != time_column}
    for name, a in numeric.items():
        if name == time_column:
            continue
        if a.ndim == 1 or (a.ndim == 2 and 1 in a.shape and a.size == n):
            if a.size != n:
                skipped[name] = f"{a.size} samples, time has {n}"
                continue
            cols[name] = a.ravel()
            continue
        if a.ndim != 2:
            skipped[name] = f"shape {a.shape} is not a vector or a matrix"
            continue
        # Samples along the axis whose length is that of time; MATLAB's HDF5 layout is
        # transposed, so there prefer the first axis as the column index when square.
        if a.shape[0] == n and not (transposed and a.shape[1] == n):
            a2 = a
        elif a.shape[1] == n:
            a2 = a.T
        elif a.shape[0] == n:
            a2 = a
        else:
            skipped[name] = f"shape {a.shape}, time has {n} samples"
            continue
        for k in range(a2.shape[1]):
            cols[f"{name}_{k}"] = a2[:, k]
    values, valid = {}, {}
    for name, v in cols.items():
        v = v.astype(np.float64)
        ok = np.isfinite(v)
        v[~ok] = np.nan
        values[name], valid[name] = v, ok
    return MeasuredData(source, time, values, valid), skipped


def _attr_str(value) -> str | None:
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    return None if value is None else str(value)


def _first_bad_time(time: np.ndarray) -> int | None:
    """Index of the first non-finite or non-increasing time stamp, or None."""
    bad = np.flatnonzero(~np.isfinite(time))
    first = int(bad[0]) if bad.size else None
    with np.errstate(invalid="ignore"):
        step = np.flatnonzero(~(np.diff(time) > 0)) + 1
    step = step[np.isfinite(time[step]) & np.isfinite(time[step - 1])]
    if step.size and (first is None or step[0] < first):
        first = int(step[0])
    return first


def _bad_time_reason(time: np.ndarray, i: int) -> str:
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


# --------------------------------------------------------------------------- time base

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


# --------------------------------------------------------------------------- noise

@dataclass(frozen=True)
class NoiseEstimate:
    """Noise of one column, from the valid samples before ``t_end``.

    ``sigma``: standard deviation of the (detrended) samples, the white-noise level.
    ``phi``: lag-1 autocorrelation, the AR(1) coefficient *per sample interval* (so it
    depends on the recorder rate; ``dt`` is the median interval it refers to).
    ``sigma_innovation``: the AR(1) driving-noise level, ``sigma * sqrt(1 - phi**2)``.
    ``n``: samples used.
    """

    column: str
    sigma: float
    phi: float
    sigma_innovation: float
    n: int
    dt: float
    t_end: float
    detrend: bool


def noise_level(data: MeasuredData, column: str, t_end: float,
                detrend: bool = True) -> NoiseEstimate:
    """Measurement noise of ``column`` from the quiet samples before ``t_end``.

    Estimator: take the valid samples with ``time < t_end``; subtract a least-squares
    straight line in time (``detrend=True``, which removes a slow drift) or the mean.
    With residuals ``r`` and ``p`` fitted coefficients (2 or 1):

    * ``sigma = sqrt(sum r**2 / (n - p))``, the unbiased white-noise estimate;
    * ``phi = mean(r[i] * r[i-1]) / mean(r**2)``, the Yule-Walker lag-1 estimate, where
      the numerator runs over pairs of consecutive samples that are both valid (a gap
      breaks the chain rather than joining samples either side of it);
    * ``sigma_innovation = sigma * sqrt(1 - phi**2)``, from the stationary AR(1)
      variance ``sigma**2 = sigma_e**2 / (1 - phi**2)``.

    Jitter in the time stamps is ignored: consecutive samples count as one interval.
    Yule-Walker ``phi`` is biased towards zero by about ``(1 + 3 phi) / n``.
    """
    valid = data._valid(column)
    use = valid & (data.time < t_end)
    n = int(np.count_nonzero(use))
    if n < MIN_NOISE_SAMPLES:
        raise DataError(f"only {n} valid '{column}' samples before t = {t_end:g} s; the noise "
                        f"level needs at least {MIN_NOISE_SAMPLES}", data.source)
    t = data.time[use]
    y = data.columns[column][use]
    if detrend:
        A = np.column_stack([np.ones_like(t), t - t.mean()])
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        r_used = y - A @ coef
        p = 2
    else:
        r_used = y - y.mean()
        p = 1
    ss = float(np.sum(r_used ** 2))
    sigma = float(np.sqrt(ss / (n - p)))
    # Residuals back on the full index so that consecutive pairs are found across gaps.
    r = np.zeros(data.time.shape)
    r[use] = r_used
    pair = use[1:] & use[:-1]
    n_pairs = int(np.count_nonzero(pair))
    if n_pairs == 0 or ss == 0.0:
        phi = 0.0
    else:
        phi = float((np.sum(r[1:][pair] * r[:-1][pair]) / n_pairs) / (ss / n))
    phi = float(np.clip(phi, -1.0, 1.0))
    dt = float(np.median(np.diff(t))) if n > 1 else float("nan")
    return NoiseEstimate(column, sigma, phi, sigma * float(np.sqrt(1.0 - phi ** 2)),
                         n, dt, float(t_end), detrend)


def ar1_inflation(phi: float) -> float:
    """Variance factor ``(1 + phi) / (1 - phi)`` of a mean of AR(1) noise of lag-1
    correlation ``phi`` (negative phi taken as 0, phi capped at 0.99)."""
    phi = min(max(float(phi), 0.0), 0.99)
    return (1 + phi) / (1 - phi)
