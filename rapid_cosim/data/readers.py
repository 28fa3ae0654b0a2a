"""Recordings from files: :func:`load_measurements` reads one into a
:class:`~rapid_cosim.data.measured.MeasuredData` and warns
(:class:`~rapid_cosim.data.measured.MaskedSamplesWarning`) when it has masked samples.

Formats, chosen by the file suffix:

``.csv``
    A header row of column names, then one sample per row. The delimiter (``,``, ``;``
    or tab) is the one that splits the header and the first rows alike, or is given
    (``delimiter``); where two would do, the file is refused at its row rather than
    guessed. The decimal separator is ``.`` or, given, ``,`` (``decimal``; then the
    delimiter is ``;`` or tab, and a ``.`` in a number is refused: it would be a
    thousands separator or another export's number). A UTF-8 BOM and CRLF line ends are
    read. A row right under the header with no number in it is a units row (``s;Hz;MW``,
    as historians write): skipped and said (:class:`SkippedRowWarning`,
    :attr:`MeasuredData.notes`), and a time unit it states must agree with
    ``time_unit``. An empty cell or ``nan`` is a missing sample (so is ``inf``: a
    recorder overflow is no reading). Any other text that is not a number is a
    :class:`DataError`.
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
``.cfg`` / ``.cff``
    IEEE C37.111 COMTRADE (:mod:`.comtrade`): every analog channel by its name, scaled
    to primary values; time in seconds from the first sample.
``.csv`` with ``timestamp``
    A PMU export (:mod:`.pmu`): absolute timestamps, in seconds from an event time.

Rows in error messages are counted as a spreadsheet shows them: the header is row 1,
the first sample row 2. For MAT and HDF5 files, errors name the 1-based sample number.

Time must be finite; repeated and late stamps are settled as :mod:`.timebase` says
(repeats that agree dropped, late frames sorted, both said in a
:class:`~.timebase.TimeBaseWarning`), and anything else is rejected at its row.
``time_unit`` converts a time column in milliseconds or microseconds.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import DataError
from . import comtrade
from .csv_table import SkippedRowWarning, check_dialect, read_csv_table
from .measured import MaskedSamplesWarning, MeasuredData, MissingColumn, from_recorded
from .pmu import read_pmu_csv
from .timebase import TimeBaseWarning

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}

CSV_SUFFIXES = (".csv",)
MAT_SUFFIXES = (".mat",)
HDF5_SUFFIXES = (".h5", ".hdf5", ".hdf")
def split_hdf5_path(path: str | Path) -> tuple[Path, str]:
    """``'run.h5:/a/b'`` -> ``(Path('run.h5'), '/a/b')``; no group -> ``'/'``."""
    text = str(path)
    m = re.match(r"^(.*\.(?:h5|hdf5|hdf|mat)):(/.*)$", text, flags=re.IGNORECASE)
    if m:
        return Path(m.group(1)), m.group(2)
    return Path(text), "/"


def load_measurements(path: str | Path, time_column: str = "time",
                      columns: Mapping[str, str] | None = None,
                      warn: bool = True, *, timestamp: str | None = None,
                      event_time: str | float | None = None, time_unit: str = "s",
                      delimiter: str | None = None, decimal: str = ".") -> MeasuredData:
    """Read a recording (CSV, MAT, HDF5 or COMTRADE, by suffix) into a :class:`MeasuredData`.

    ``timestamp`` names a CSV column of absolute timestamps (a PMU export,
    :mod:`.pmu`): time is then in seconds from ``event_time``. ``delimiter`` (None:
    detected) and ``decimal`` say how a CSV is written; other formats ignore them.

    ``columns`` maps the names wanted to the names in the file (``{"pm": "signal_0"}``);
    when given, only those columns are kept, and a missing one is a
    :class:`MissingColumn` error listing what the file has. With ``warn``, warnings say
    what reading skipped (:class:`SkippedRowWarning`), repaired and masked
    (:class:`MaskedSamplesWarning`).
    """
    if time_unit not in TIME_UNITS:
        raise DataError(f"time unit {time_unit!r} is not known; allowed: {', '.join(TIME_UNITS)}", str(path))
    check_dialect(delimiter, decimal, str(path))
    file, group = split_hdf5_path(path)
    suffix = file.suffix.lower()
    if group != "/" and suffix not in HDF5_SUFFIXES:
        raise DataError(f"a group ({group}) can only be given for HDF5 files", str(path))
    if not file.is_file():
        raise DataError(f"file not found: {file.resolve()}", str(file))
    source = str(path)
    skipped: dict[str, str] = {}
    if suffix in CSV_SUFFIXES and timestamp is not None:
        data = read_pmu_csv(file, timestamp, event_time, delimiter=delimiter, decimal=decimal)
    elif suffix in comtrade.SUFFIXES:
        data = comtrade.read_comtrade(file)
    elif suffix in CSV_SUFFIXES:
        data = _read_csv(file, source, time_column, time_unit, delimiter, decimal)
    elif suffix in MAT_SUFFIXES:
        data, skipped = _read_mat(file, source, time_column, TIME_UNITS[time_unit])
    elif suffix in HDF5_SUFFIXES:
        data, skipped = _read_hdf5(file, group, source, time_column, TIME_UNITS[time_unit])
    else:
        supported = ", ".join(CSV_SUFFIXES + MAT_SUFFIXES + HDF5_SUFFIXES + comtrade.SUFFIXES)
        raise DataError(f"unknown file type '{file.suffix}'; supported: {supported}", source)
    if columns is not None:
        for stored in columns.values():
            if stored not in data.columns:
                raise MissingColumn(stored, list(data.names), source, skipped)
        data = MeasuredData(source, data.time,
                            {new: data.columns[old] for new, old in columns.items()},
                            {new: data.valid[old] for new, old in columns.items()}, data.rows, data.repairs,
                            data.notes, {new: data.units[old] for new, old in columns.items() if old in data.units})
    if warn and data.notes:
        warnings.warn(f"{source}: " + "; ".join(data.notes), SkippedRowWarning, stacklevel=2)
    if warn and data.repairs:
        warnings.warn(f"{source}: " + "; ".join(data.repairs.words), TimeBaseWarning, stacklevel=2)
    if warn and data.gaps():
        warnings.warn(data.gap_report(), MaskedSamplesWarning, stacklevel=2)
    return data


def _read_csv(file: Path, source: str, time_column: str, time_unit: str = "s", delimiter: str | None = None,
              decimal: str = ".") -> MeasuredData:
    table = read_csv_table(file, source, time_column, delimiter, decimal)
    table.check_time_unit(time_column, time_unit)
    values = table.numbers(table.names)
    t = table.names.index(time_column)
    return from_recorded(values[:, t] * TIME_UNITS[time_unit],
                         {n: values[:, k] for k, n in enumerate(table.names) if k != t},
                         source, time_column, table.rows, notes=table.notes,
                         units={n: u for n, u in table.units.items() if u and n != time_column})


def _read_mat(file: Path, source: str, time_column: str,
              time_scale: float = 1.0) -> tuple[MeasuredData, dict[str, str]]:
    import h5py

    if h5py.is_hdf5(file):  # MAT v7.3
        with h5py.File(file, "r") as f:
            arrays = {k: np.asarray(f[k]) for k, obj in f.items()
                      if isinstance(obj, h5py.Dataset) and not k.startswith("#")
                      and _attr_str(obj.attrs.get("MATLAB_class")) not in ("char", "cell", "struct")}
        return _from_arrays(arrays, source, time_column, transposed=True, time_scale=time_scale)
    import scipy.io

    try:
        raw = scipy.io.loadmat(str(file))
    except (ValueError, TypeError, NotImplementedError) as e:
        raise DataError(f"cannot read MAT file: {e}", source) from None
    arrays = {k: v for k, v in raw.items() if not k.startswith("__") and isinstance(v, np.ndarray)}
    return _from_arrays(arrays, source, time_column, transposed=False, time_scale=time_scale)


def _read_hdf5(file: Path, group: str, source: str, time_column: str,
               time_scale: float = 1.0) -> tuple[MeasuredData, dict[str, str]]:
    import h5py

    with h5py.File(file, "r") as f:
        if group not in f or not isinstance(f[group], h5py.Group):
            groups: list[str] = []
            f.visititems(lambda name, obj: groups.append("/" + name)
                         if isinstance(obj, h5py.Group) else None)
            raise DataError(f"no group '{group}'; groups present: {', '.join(['/'] + groups)}", source)
        g = f[group]
        arrays = {k: np.asarray(obj) for k, obj in g.items() if isinstance(obj, h5py.Dataset)}
    return _from_arrays(arrays, source, time_column, transposed=False, time_scale=time_scale)


def _from_arrays(arrays: dict[str, np.ndarray], source: str, time_column: str,
                 transposed: bool, time_scale: float = 1.0) -> tuple[MeasuredData, dict[str, str]]:
    """Columns from named arrays that share the length of ``time``; the rest are skipped
    with a reason (so that asking for one of them says why it is not there)."""
    numeric = {k: v for k, v in arrays.items()
               if v.dtype.kind in "biuf" and v.size > 0}
    if time_column not in numeric:
        raise MissingColumn(time_column, sorted(k for k in arrays if k != time_column), source)
    time = numeric[time_column]
    if time.ndim > 2 or (time.ndim == 2 and min(time.shape) != 1):
        raise DataError(f"'{time_column}' must be a vector, it has shape {time.shape}", source)
    time = time.astype(np.float64).ravel() * time_scale
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
    return from_recorded(time, cols, source, time_column), skipped


def _attr_str(value) -> str | None:
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    return None if value is None else str(value)
