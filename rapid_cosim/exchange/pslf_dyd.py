"""PSLF ``.dyd`` records of tgov1, ieeeg1, ggov1, hygov and gast: write one, read them back.

A ``.dyd`` record names its machine by bus number, bus name, base kV and unit id, then
the model's base and data after a colon::

    tgov1 1 "GEN1" 20.0 "1" : #9 mva=900.0 "r" 0.05 "t1" 0.5 "vmax" 1.0 ...

A line ending in ``/`` continues on the next. The data are written as keyword pairs
(``"name" value``, the form PSLF writes and reads for every model, so that no value
depends on its position); reading also accepts ``name=value`` pairs and the positional
form (values in PSLF's order, :attr:`.tables.Model.pslf_order`). ``mva=`` is the machine's
MVA base, the base of the pu values (unchanged from iGrGen, see :mod:`.tables`), and must
be given when writing. Fields that PSLF has and PSS/E has not (ieeeg1's and hygov's
deadbands ``db1``/``eps``/``db2`` and gate-power curves ``gv``/``pgv``) are not written, so
PSLF takes its defaults (none); a record that gives them is rejected as a field the iGrGen
model has not. A fit with a speed deadband (TGOV1, IEEEG1, HYGOV's ``db``) has no ``.dyd``
layout here: PSLF's tgov1 has no deadband, and its ieeeg1 and hygov ``db1`` is in Hz with a
hysteresis ``eps``, a form this package does not model; such a record is refused with
that reason, and its ``.dyr`` (TGOV1D, IEEEG1D, HYGOVD) carries the deadband. PSS/E-only fields (IEEEG1's ``JBUS``/``M``, GGOV1's ``Trate``) have no PSLF
keyword: ``mva=`` is the base.

Sources and their limits: the keyword names and positional orders follow PSLF as public
secondary sources show it: the CIM dynamics classes derived from PSLF's models
(``GovSteam0`` for tgov1, ``GovSteamIEEE1`` for ieeeg1, ``GovCT1`` for ggov1 with its
``pmwset`` after ``kimw``, ``GovHydro1`` for hygov's ``rperm``/``rtemp``), and readers of
PSLF files (GridDyn takes hygov's first 12, ieeeg1's first 20 and ggov1's first 35
positional values). GE's PSLF manual was not available to check them: check the first
exported record in PSLF. Positional records of ieeeg1 and hygov longer than these
prefixes (PSLF's deadband and gate-curve extensions) are rejected, not truncated.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Mapping

from ..errors import ParameterError, RecordError
from .layouts import LAYOUTS, layout
from .tables import (Model, NoLayout, Other, Record, Written, choose, number_text, record_numbers,
                     values_from_numbers)

PSLF_LAYOUTS = {name: m for name, m in LAYOUTS.items() if m.pslf}

_TOKEN = re.compile(r"\"[^\"]*\"|'[^']*'|[^\s]+")
PAIRS_PER_LINE = 6


def format_record(model: str, values: Mapping[str, float], *, bus: int, machine_id: str = "1", mva: float,
                  bus_name: str = "", kv: float = 0.0,
                  extra: Mapping[str, float] | None = None) -> tuple[str, dict[str, float]]:
    """The record text of iGrGen ``values`` (names without the bench's ``gov.``) and the
    dropped values (see :func:`.tables.record_numbers`)."""
    table = layout(model, values)
    if not table.pslf:
        theirs = ("has no deadband" if table.block == "TGOV1" else
                  "has db1 in Hz with a hysteresis eps, another form of deadband")
        raise NoLayout(f"{table.block} with a deadband (db = {values.get('db', 0):g} pu) has no PSLF layout "
                             f"here: PSLF's {table.block.lower()} {theirs}; the .dyr's {table.name} record carries it")
    if mva is None or not mva > 0:
        raise ParameterError(f"a .dyd record needs the machine's MVA base (mva > 0), got {mva!r}")
    _power_controller(table, values.get("Kimw", 0.0), None, 0)
    numbers, dropped = record_numbers(table, values, extra)
    by_field = {f.pslf: number_text(v, f.integer) for f, v in numbers if f.pslf is not None}
    pairs = [f'"{name}" {by_field[name]}' for name in table.pslf_order]
    head = (f'{table.pslf_name} {int(bus)} "{bus_name}" {number_text(kv)} "{machine_id}" : #9 '
            f"mva={number_text(mva)}")
    lines = [head] + ["  " + " ".join(pairs[k:k + PAIRS_PER_LINE]) for k in range(0, len(pairs), PAIRS_PER_LINE)]
    return " /\n".join(lines) + "\n", dropped


def write_record(path: str | Path, model: str, values: Mapping[str, float], *, bus: int, machine_id: str = "1",
                 mva: float, bus_name: str = "", kv: float = 0.0,
                 extra: Mapping[str, float] | None = None) -> Written:
    """Write one record to ``path`` (replacing the file)."""
    text, dropped = format_record(model, values, bus=bus, machine_id=machine_id, mva=mva, bus_name=bus_name, kv=kv,
                                  extra=extra)
    Path(path).write_text(text)
    return Written(layout(model, values).name, text, str(path), dropped)


def parse_records(text: str, file: str = "<text>", *,
                  errors: list[tuple[Other, RecordError]] | None = None) -> tuple[list[Record], list[Other]]:
    """Every tgov1/ieeeg1/ggov1/hygov/gast record of ``text``, and the other models'
    records (their names, lines, bus and id). A record that cannot be read raises, or
    with ``errors`` (a list) is put there with where it applies, and the rest are read."""
    records, others = [], []
    for line, body in _logical_lines(text):
        try:
            parsed = _parse_one(line, body, file)
        except RecordError as e:
            tokens = _TOKEN.findall(body.partition(":")[0])
            if errors is None or len(tokens) < 5:
                raise
            errors.append((Other(tokens[0], _int_or_none(tokens[1]), tokens[4].strip("\"'").strip(), line), e))
            continue
        if parsed is not None:
            (records if isinstance(parsed, Record) else others).append(parsed)
    return records, others


def _parse_one(line: int, body: str, file: str) -> Record | Other | None:
    """One logical line: a Record of a layout read here, the Other it is, or None (a
    section header)."""
    head, colon, data = body.partition(":")
    tokens = _TOKEN.findall(head)
    if not colon:
        if len(tokens) == 1:  # a section header: models, lodrep, end
            return None
        raise RecordError("a record needs 'model bus \"name\" kv \"id\" : data'", file, line)
    if not tokens or tokens[0].upper() not in PSLF_LAYOUTS:
        return Other(tokens[0] if tokens else "?", _int_or_none(tokens[1]) if len(tokens) > 1 else None,
                     tokens[4].strip("\"'").strip() if len(tokens) > 4 else None, line)
    table = PSLF_LAYOUTS[tokens[0].upper()]
    if len(tokens) < 5:
        raise RecordError(f"{table.pslf_name} needs bus, \"name\", kv and \"id\" before ':', got "
                          f"{' '.join(tokens[1:])!r}", file, line)
    bus = _number(tokens[1], "bus", file, line, int)
    kv = _number(tokens[3], "kv", file, line, float)
    mva, fields = _fields(table, _TOKEN.findall(data), file, line)
    values, extra = values_from_numbers(table, fields, file, line, mva)
    _power_controller(table, values.get("Kimw", 0.0), file, line)
    return Record(table.name, values, bus, tokens[4].strip("\"'").strip(), mva, extra, file, line,
                  tokens[2].strip("\"'").strip(), kv, family=table.block)


def read_record(path: str | Path, *, bus: int | None = None, machine_id: str | None = None) -> Record:
    """The one governor record of a file (of ``bus``/``machine_id`` when it holds several)."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise RecordError(f"cannot read the file: {e.strerror}", str(path)) from None
    bad: list[tuple[Other, RecordError]] = []
    records, others = parse_records(text, str(path), errors=bad)
    return choose(records, others, str(path), bus, machine_id, ", ".join(m.pslf_name for m in PSLF_LAYOUTS.values()),
                  bad)


def _fields(table: Model, tokens: list[str], file: str, line: int) -> tuple[float | None, dict[str, tuple[str, str]]]:
    """The base and each field's (name as written, text) from the data after ':'."""
    mva = None
    keyed: dict[str, tuple[str, str]] = {}
    positional: list[str] = []
    by_pslf = table.by_pslf()
    k = 0
    while k < len(tokens):
        token = tokens[k]
        k += 1
        if token.startswith("#"):
            continue
        if token.lower().startswith("mva="):
            mva = _number(token[4:], "mva", file, line, float)
            continue
        if token[0] in "\"'" or "=" in token:
            if token[0] in "\"'":
                if k >= len(tokens):
                    raise RecordError("a keyword without a value", file, line, token.strip("\"'"), None)
                name, value = token.strip("\"'").strip(), tokens[k]
                k += 1
            else:
                name, _, value = token.partition("=")
            f = by_pslf.get(name.lower())
            if f is None:
                raise RecordError(f"{table.pslf_name} has no such field", file, line, name, value,
                                  " ".join(table.pslf_order))
            if f.key in keyed:
                raise RecordError("given twice", file, line, name, value)
            keyed[f.key] = (name, value)
        else:
            positional.append(token)
    if keyed and positional:
        raise RecordError("mixes keyword and positional values", file, line, None, None,
                          "one form: \"name\" value pairs, or every value in order")
    if not keyed:
        if len(positional) != len(table.pslf_order):
            raise RecordError(f"{table.pslf_name} takes {len(table.pslf_order)} values, the record has "
                              f"{len(positional)}", file, line, None, None, " ".join(table.pslf_order))
        keyed = {by_pslf[n].key: (n, t) for n, t in zip(table.pslf_order, positional)}
    missing = [f.pslf for f in table.fields if f.pslf is not None and f.key not in keyed]
    if missing:
        raise RecordError(f"{table.pslf_name} misses {', '.join(missing)}", file, line, None, None,
                          " ".join(table.pslf_order))
    for f in table.fields:  # PSS/E-only fields: their neutral value
        keyed.setdefault(f.key, (f.key, number_text(f.default, f.integer)))
    return mva, keyed


def _logical_lines(text: str):
    """(first line, text) of each record, continuation lines ('/' at the end) joined;
    blank lines and comments ('#' first) skipped."""
    parts: list[str] = []
    start = 0
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not parts and (not line or line.startswith("#")):
            continue
        if not parts:
            start = n
        if line.endswith("/"):
            parts.append(line[:-1])
            continue
        parts.append(line)
        yield start, " ".join(parts)
        parts = []
    if parts:
        yield start, " ".join(parts)


def _int_or_none(text: str) -> int | None:
    try:
        return int(text)
    except ValueError:
        return None


def _number(text: str, name: str, file: str, line: int, kind):
    try:
        return kind(text)
    except ValueError:
        raise RecordError(f"not {'an integer' if kind is int else 'a number'}", file, line, name, text) from None


def _power_controller(table: Model, kimw: float, file: str | None, line: int) -> None:
    """ggov1's power controller (kimw > 0) drives the power to ``pmwset``, a set-point in
    MW that PSLF takes from the record; iGrGen's follows each event's dispatch, as PSS/E's
    does (it takes the set-point from the initial power). Where the controller acts the
    two differ, and what PSLF makes of a record's ``pmwset`` 0 was not available to check
    (GE's manual), so such a record is neither written nor read: a .dyr carries it."""
    if table.name != "GGOV1" or kimw <= 0:
        return
    if file is None:
        raise ParameterError(f"GGOV1 with Kimw = {kimw:g} (a power controller): a PSLF ggov1 record states its "
                             "set-point pmwset in MW, where the fitted model follows each event's dispatch; write the "
                             ".dyr (PSS/E takes the set-point from the initial power) or hold Kimw at 0")
    raise RecordError("a power controller (kimw > 0) on PSLF's set-point pmwset is not converted: iGrGen's follows "
                      "the dispatch (a PSS/E .dyr record carries it)", file, line, "kimw", kimw, "0")
