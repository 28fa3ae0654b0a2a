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

import csv
import re
from datetime import datetime, timezone
from decimal import Decimal
from pathlib import Path

import numpy as np

from ..errors import DataError
from .measured import MeasuredData, MissingColumn, from_recorded

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


def read_pmu_csv(path: str | Path, timestamp: str, event_time: str | float | None = None) -> MeasuredData:
    """Every numeric column of a PMU export, on seconds from ``event_time`` (a timestamp
    as in the file, or epoch seconds; default: the first row's)."""
    path = Path(path)
    source = str(path)
    with open(path, newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None:
            raise DataError("the file is empty", source)
        names = [h.strip() for h in header]
        if timestamp not in names:
            raise MissingColumn(timestamp, [n for n in names if n != timestamp], source)
        t_index = names.index(timestamp)
        stamps, values, rows = [], [], []
        for record in reader:
            if not record or all(not c.strip() for c in record):
                continue
            row = reader.line_num
            if len(record) != len(names):
                raise DataError(f"expected {len(names)} fields ({', '.join(names)}), found {len(record)}", source, row)
            try:
                stamps.append(parse_timestamp(record[t_index]))
            except ValueError as e:
                raise DataError(f"column '{timestamp}': {record[t_index]!r} is not a timestamp ({e})", source,
                                row) from None
            parsed = []
            for k, (name, cell) in enumerate(zip(names, record)):
                if k == t_index:
                    continue
                cell = cell.strip()
                try:
                    parsed.append(float(cell) if cell else np.nan)
                except ValueError:
                    raise DataError(f"column '{name}': {cell!r} is not a number", source, row) from None
            values.append(parsed)
            rows.append(row)
    if not stamps:
        raise DataError("the file has a header but no samples", source)
    if event_time is None:
        origin = stamps[0]
    else:
        try:
            origin = parse_timestamp(str(event_time))
        except ValueError as e:
            raise DataError(f"event time {event_time!r} is not a timestamp ({e})", source) from None
    time = (np.asarray(stamps, dtype=np.int64) - origin) / 1e6
    table = np.asarray(values, dtype=float).reshape(len(values), -1)
    others = [n for k, n in enumerate(names) if k != t_index]
    return from_recorded(time, {n: table[:, k] for k, n in enumerate(others)}, source, timestamp, np.asarray(rows))
