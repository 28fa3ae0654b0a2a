"""PMU exports: CSV files whose time column holds absolute timestamps, several channels
per file, turned into seconds from a stated event time.

A timestamp is ISO 8601 (``2024-03-01T12:00:00.020Z``, ``2024-03-01 12:00:00.02+01:00``;
one without a zone is taken as UTC) or Unix epoch seconds (``1709294400.02``). Time is
kept in whole microseconds until the subtraction, so 50 frames per second stay exactly
20 ms apart. Repeated and late frames are settled as :mod:`.timebase` says (a repeat
whose values disagree, or a frame more than one early, is an error at its row); a leap
second (``:60``) is an error, as its meaning depends on the recorder's clock. Missing rows are a gap in time, not an error: as
outputs they simply give fewer samples; as a model input, the experiment refuses a gap
longer than its sample rate allows.
"""

from __future__ import annotations

import re
from datetime import datetime, timezone
from decimal import Decimal
from pathlib import Path

import numpy as np

from .csv_table import read_csv_table
from ..errors import DataError
from .measured import MeasuredData, from_recorded

_EPOCH = datetime(1970, 1, 1, tzinfo=timezone.utc)
_NUMBER = re.compile(r"^[+-]?\d+(\.\d*)?$")


def parse_timestamp(text: str) -> int:
    """Microseconds since the Unix epoch, UTC."""
    text = text.strip()
    if _NUMBER.match(text):
        return int(Decimal(text) * 1_000_000)
    if re.search(r"T?\d{2}:\d{2}:60", text):
        raise ValueError("a leap second (:60): convert the export to a clock without them")
    stamp = datetime.fromisoformat(text.replace("z", "Z"))
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=timezone.utc)
    delta = stamp - _EPOCH
    return (delta.days * 86400 + delta.seconds) * 1_000_000 + delta.microseconds


def read_pmu_csv(path: str | Path, timestamp: str, event_time: str | float | None = None, *,
                 delimiter: str | None = None, decimal: str = ".") -> MeasuredData:
    """Every numeric column of a PMU export, on seconds from ``event_time`` (a timestamp
    as in the file, or epoch seconds; default: the first row's). The CSV dialect is read
    as :mod:`.readers` reads it (delimiter detected or given, decimal comma, units row)."""

    path = Path(path)
    source = str(path)
    table = read_csv_table(path, source, timestamp, delimiter, decimal, text_columns=(timestamp,))
    stamps = _stamps(table.cells[:, table.names.index(timestamp)], table.rows, timestamp, decimal, source)
    if event_time is None:
        origin = int(stamps[0])
    else:
        try:
            origin = parse_timestamp(str(event_time))
        except ValueError as e:
            raise DataError(f"event time {event_time!r} is not a timestamp ({e})", source) from None
    time = (stamps - origin) / 1e6
    others = [n for n in table.names if n != timestamp]
    values = table.numbers(others)
    return from_recorded(time, {n: values[:, k] for k, n in enumerate(others)}, source, timestamp, table.rows,
                         notes=table.notes)


def _stamps(cells: np.ndarray, rows: np.ndarray, name: str, decimal: str, source: str) -> np.ndarray:
    """Microseconds since the epoch of each cell; with a decimal comma, epoch seconds and
    fractions of a second are written with one."""
    stamps = np.empty(len(cells), dtype=np.int64)
    for i, cell in enumerate(cells.tolist()):
        try:
            stamps[i] = parse_timestamp(cell.replace(",", ".") if decimal == "," else cell)
        except ValueError as e:
            raise DataError(f"column '{name}': {cell!r} is not a timestamp ({e})", source, int(rows[i])) from None
    return stamps
