"""PSS/E ``.dyr`` records of TGOV1, IEEEG1, GGOV1, HYGOV and GAST, and the deadband layouts
TGOV1D, IEEEG1D and HYGOVD: write one, read them back.

A ``.dyr`` record is free-format text ended by ``/``::

    IBUS 'MODEL' ID  ICON(M) ... CON(J) ... /

with the ICONs (integers) before the CONs, each in the order of the PSS/E Model Library
(the tables in :mod:`.tables`; the same orders as andes' ``andes/io/psse-dyr.yaml``):

* TGOV1: R T1 VMAX VMIN T2 T3 Dt
* IEEEG1: JBUS M | K T1 T2 T3 Uo Uc PMAX PMIN T4 K1 K2 T5 K3 K4 T6 K5 K6 T7 K7 K8
* GGOV1: Rselect Flag | R Tpelec maxerr minerr Kpgov Kigov Kdgov Tdgov Vmax Vmin Tact Kturb
  Wfnl Tb Tc Teng Tfload Kpload Kiload Ldref Dm Ropen Rclose Kimw Aset Ka Ta Trate db Tsa
  Tsb Rup Rdown
* HYGOV: R r Tr Tf Tg VELM GMAX GMIN TW At Dturb qNL
* GAST: R T1 T2 T3 AT KT VMAX VMIN Dturb
* TGOV1D, IEEEG1D, HYGOVD (PowerWorld, ORNL GridKit): the plain model's fields, then dbH
  dbL Trate. A block with a deadband is written in its D layout; without one, in the plain
  layout, so a record without a deadband reads as it always did.

Values are pu on the machine's MVA base, as in iGrGen, so they are written unchanged; the
record carries no base (PSS/E takes MBASE from the ``.raw`` generator record, andes converts
power quantities to its system base from it). Every other conversion, and what is
written for the iGrGen parameters that have no field, is in :mod:`.tables`.

Writing gives one record in a canonical layout (five numbers a line, each number the
shortest text that reads back to the same float), so a record read and written again is
the same text. Reading accepts any free-format layout, several records a file, other
models' records (skipped: a unit's whole ``.dyr`` can be read), quotes or none around the
model name and the machine id, and Fortran ``D`` exponents; text after a ``/`` is a
comment.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Mapping

from ..errors import RecordError
from .layouts import LAYOUTS, SUPPORTED, layout
from .tables import Other, Record, Written, choose, number_text, record_numbers, values_from_numbers

_TOKEN = re.compile(r"'[^']*'|\"[^\"]*\"|[^\s,]+")
PER_LINE = 5


def format_record(model: str, values: Mapping[str, float], *, bus: int, machine_id: str = "1",
                  extra: Mapping[str, float] | None = None) -> tuple[str, dict[str, float]]:
    """The record text of iGrGen ``values`` (parameter names without the bench's ``gov.``)
    and the dropped values (see :func:`.tables.record_numbers`), in the layout that carries
    them (TGOV1 with a deadband: TGOV1D)."""
    table = layout(model, values)
    numbers, dropped = record_numbers(table, values, extra)
    head = f"{int(bus)} '{table.name}' {_machine_id(machine_id)}"
    texts = [number_text(v, f.integer) for f, v in numbers if f.psse is not None]
    lines = [" ".join([head, *texts[:PER_LINE]])]
    lines += ["    " + " ".join(texts[k:k + PER_LINE]) for k in range(PER_LINE, len(texts), PER_LINE)]
    return "\n".join(lines) + " /\n", dropped


def write_record(path: str | Path, model: str, values: Mapping[str, float], *, bus: int, machine_id: str = "1",
                 extra: Mapping[str, float] | None = None) -> Written:
    """Write one record to ``path`` (replacing the file)."""
    text, dropped = format_record(model, values, bus=bus, machine_id=machine_id, extra=extra)
    Path(path).write_text(text)
    return Written(layout(model, values).name, text, str(path), dropped)


def parse_records(text: str, file: str = "<text>", *, mva: float | None = None,
                  errors: list[tuple[Other, RecordError]] | None = None) -> tuple[list[Record], list[Other]]:
    """Every record of ``text`` in a layout this package reads, and the other models'
    records (``GENROU (line 3)``, with their bus and id). ``mva`` (the machine base, if
    known) lets a record with ``Trate`` equal to it be read. A record that cannot be read
    raises, or with ``errors`` (a list) is put there with where it applies, and the rest
    are read: one machine's bad record in a planning case is that machine's problem."""
    records, others = [], []
    for line, tokens in _raw_records(text):
        try:
            parsed = _parse_one(line, tokens, file, mva)
        except RecordError as e:
            if errors is None or len(tokens) < 3:
                raise
            errors.append((Other(tokens[1].strip("'\"").strip(), _bus_or_none(tokens[0]),
                                 tokens[2].strip("'\"").strip(), line), e))
            continue
        (records if isinstance(parsed, Record) else others).append(parsed)
    return records, others


def _parse_one(line: int, tokens: list[str], file: str, mva: float | None) -> Record | Other:
    """One record's tokens: a Record of a layout read here, or the Other it is."""
    if len(tokens) < 3:
        raise RecordError(f"a record needs at least IBUS 'MODEL' ID, got {' '.join(tokens)!r}", file, line)
    name = tokens[1].strip("'\"").strip()
    if name.upper() not in LAYOUTS:
        return Other(name, _bus_or_none(tokens[0]), tokens[2].strip("'\"").strip(), line)
    table = LAYOUTS[name.upper()]
    bus = _bus(tokens[0], file, line)
    numbers, own = tokens[3:], table.psse_fields
    if len(numbers) != len(own):
        raise RecordError(f"{table.name} takes {len(own)} values, the record has {len(numbers)}", file, line,
                          None, None, " ".join(f.psse for f in own))
    fields = {f.key: (f.key, number_text(f.default, f.integer)) for f in table.fields}  # PSLF-only: neutral
    fields.update({f.key: (f.psse, t) for f, t in zip(own, numbers)})
    values, extra = values_from_numbers(table, fields, file, line, mva)
    return Record(table.name, values, bus, tokens[2].strip("'\"").strip(), None, extra, file, line,
                  family=table.block)


def read_record(path: str | Path, *, bus: int | None = None, machine_id: str | None = None,
                mva: float | None = None) -> Record:
    """The one governor record of a file (of ``bus``/``machine_id`` when the file holds
    several)."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise RecordError(f"cannot read the file: {e.strerror}", str(path)) from None
    bad: list[tuple[Other, RecordError]] = []
    records, others = parse_records(text, str(path), mva=mva, errors=bad)
    return choose(records, others, str(path), bus, machine_id, SUPPORTED, bad)


def _raw_records(text: str):
    """(first line, tokens) of each record: tokens up to a ``/`` outside quotes."""
    tokens: list[str] = []
    start = 0
    for n, line in enumerate(text.splitlines(), 1):
        body, ended = _before_slash(line)
        found = _TOKEN.findall(body)
        if found and not tokens:
            start = n
        tokens += found
        if ended:
            if tokens:
                yield start, tokens
            tokens = []
    if tokens:
        raise RecordError("the record is not ended by '/'", None, start)


def _before_slash(line: str) -> tuple[str, bool]:
    quote = None
    for k, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "/":
            return line[:k], True
    return line, False


def _bus(text: str, file: str, line: int) -> int:
    try:
        return int(text)
    except ValueError:
        raise RecordError("a bus number must be an integer", file, line, "IBUS", text, "a positive integer") from None


def _bus_or_none(text: str) -> int | None:
    try:
        return int(text)
    except ValueError:
        return None


def _machine_id(machine_id: str) -> str:
    """Bare when alphanumeric (as andes reads it), else quoted."""
    machine_id = str(machine_id).strip()
    return machine_id if re.fullmatch(r"[A-Za-z0-9]{1,2}", machine_id) else f"'{machine_id}'"
