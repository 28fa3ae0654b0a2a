"""IEEE C37.111 COMTRADE recordings (``.cfg`` + ``.dat``, or one ``.cff``).

Read with the ``comtrade`` package (pinned 0.2.0): revisions 1991, 1999 and 2013; ASCII,
BINARY, BINARY32 and FLOAT32 data. It applies each channel's ``a * x + b`` scaling in
double precision (asked for explicitly: its default is single precision); a channel
recorded on the secondary side (``S`` in the .cfg) is turned into primary values with
its primary/secondary ratio here, as the package leaves that to its caller. Time is in
seconds from the first sample.

The package reads some damaged files without complaint (a .dat cut short is padded
with zeros) and reports others with bare ``ValueError``s; so the .dat is checked against
the sample count the .cfg announces, and every failure becomes a :class:`DataError`
naming the file and, where known, the channel.

:func:`write_comtrade` writes the 1999 or 2013 revision (ASCII or BINARY data): the
package has no writer, and the examples and tests need recordings in the format.
"""

from __future__ import annotations

import math
import os
from datetime import datetime, timezone
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import DataError
from .measured import MeasuredData, MissingColumn, from_recorded

SUFFIXES = (".cfg", ".cff")


def read_comtrade(path: str | Path) -> MeasuredData:
    """Every analog channel, by its name (``ch_id``), on the recording's time base."""
    import comtrade

    path = Path(path)
    source = str(path)
    _check_dat_length(path)
    try:
        rec = comtrade.load(str(path), use_double_precision=True, use_numpy_arrays=True, ignore_warnings=True)
    except (ValueError, IndexError, TypeError, KeyError, comtrade.ComtradeError, UnicodeDecodeError) as e:
        raise DataError(f"not a readable COMTRADE recording: {e}", source) from None
    time = np.asarray(rec.time, dtype=float)
    columns: dict[str, np.ndarray] = {}
    for k, (name, channel) in enumerate(zip(rec.analog_channel_ids, rec.cfg.analog_channels)):
        if name in columns:
            raise DataError(f"channel {k + 1}: the name {name!r} is used twice; channels are chosen by name", source)
        values = np.asarray(rec.analog[k], dtype=float)
        if str(channel.pors).strip().upper() == "S" and channel.secondary:
            values = values * (float(channel.primary) / float(channel.secondary))
        columns[name] = values
    return from_recorded(time, columns, source, "time")


def _check_dat_length(path: Path) -> None:
    """The .dat holds the samples the .cfg announces (the package pads a short one)."""
    if path.suffix.lower() == ".cff":
        return  # one file: cut short, its .cfg section or data section fails to parse
    if not path.is_file():
        raise DataError(f"file not found: {path.resolve()}", str(path))
    dat = path.with_suffix(".dat" if path.suffix == ".cfg" else ".DAT")
    if not dat.is_file():
        raise DataError(f"the data file {dat.name} is missing beside it", str(path))
    try:
        lines = [ln.strip() for ln in path.read_text(encoding="utf-8", errors="replace").splitlines()]
        n_channels = int(lines[1].split(",")[0])
        analog = int(lines[1].split(",")[1].strip().upper().rstrip("A"))
        digital = n_channels - analog
        rates_at = 2 + n_channels + 1
        nrates = max(int(lines[rates_at]), 1)
        last = int(lines[rates_at + nrates].split(",")[1])
        kind = lines[rates_at + nrates + 3].upper()
    except (IndexError, ValueError) as e:
        raise DataError(f"the .cfg does not follow C37.111 (line structure: {e})", str(path)) from None
    size = os.path.getsize(dat)
    if kind == "ASCII":
        rows = sum(1 for ln in dat.read_text(encoding="utf-8", errors="replace").splitlines() if ln.strip())
    else:
        width = {"BINARY": 2, "BINARY32": 4, "FLOAT32": 4}.get(kind)
        if width is None:
            raise DataError(f"unknown data file type {kind!r} in the .cfg", str(path))
        rows = size // (8 + width * analog + 2 * math.ceil(digital / 16))
    if rows < last:
        raise DataError(f"{dat.name} holds {rows} samples, the .cfg announces {last} (cut short?)", str(path))


def channel(data: MeasuredData, name: str) -> np.ndarray:
    if name not in data.columns:
        raise MissingColumn(name, list(data.names), data.source)
    return data.columns[name]


def write_comtrade(path: str | Path, time, channels: Mapping[str, np.ndarray], *, units: Mapping[str, str],
                   start: datetime, station: str = "RAPID-COSIM", device: str = "SYNTH", revision: int = 1999,
                   binary: bool = True, frequency: float = 50.0) -> Path:
    """``path`` (.cfg) and its .dat: the analog ``channels`` on ``time`` (uniform, from 0),
    16-bit integers scaled to each channel's range (its quantisation is the recorder's)."""
    path = Path(path).with_suffix(".cfg")
    time = np.asarray(time, dtype=float)
    n = time.size
    rate = (n - 1) / (time[-1] - time[0]) if n > 1 else 1.0
    lines = [f"{station},{device},{revision}", f"{len(channels)},{len(channels)}A,0D"]
    raw = []
    for k, (name, values) in enumerate(channels.items(), start=1):
        values = np.asarray(values, dtype=float)
        lo, hi = float(np.nanmin(values)), float(np.nanmax(values))
        a = max(hi - lo, 1e-12) / 65000.0
        b = (hi + lo) / 2.0
        q = np.clip(np.round((values - b) / a), -32767, 32767)
        raw.append(np.where(np.isfinite(values), q, -32768).astype("<i2"))
        lines.append(f"{k},{name},,,{units.get(name, '')},{a!r},{b!r},0,-32767,32767,1,1,P")
    stamp = start.astimezone(timezone.utc).strftime("%d/%m/%Y,%H:%M:%S.%f")
    lines += [f"{frequency:g}", "1", f"{rate:.12g},{n}", stamp, stamp, "BINARY" if binary else "ASCII", "1"]
    if revision >= 2013:
        lines += ["0,0", "0,0"]
    path.write_text("\r\n".join(lines) + "\r\n", encoding="ascii")
    stamps = np.round(time * 1e6).astype("<u4")
    if binary:
        rows = np.zeros(n, dtype=[("n", "<u4"), ("t", "<u4")] + [(f"a{k}", "<i2") for k in range(len(raw))])
        rows["n"], rows["t"] = np.arange(1, n + 1), stamps
        for k, r in enumerate(raw):
            rows[f"a{k}"] = r
        path.with_suffix(".dat").write_bytes(rows.tobytes())
    else:
        text = "".join(f"{i + 1},{stamps[i]}," + ",".join(str(int(r[i])) for r in raw) + "\r\n" for i in range(n))
        path.with_suffix(".dat").write_text(text, encoding="ascii")
    return path
