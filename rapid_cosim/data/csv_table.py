"""CSV as recorders and historians export it: the delimiter (``,``, ``;`` or tab)
detected or given, a decimal comma, a UTF-8 BOM, CRLF line ends, a units row under the
header; shared by the plain CSV reader (:mod:`.readers`) and the PMU exports' (:mod:`.pmu`).

Why a table of text first, numbers second: a dialect can only be judged on the header
and the first rows together, and an error must name the row and the cell a spreadsheet
shows, while the numbers of a 100k-row file are converted at once (numpy) and searched
cell by cell only to locate an error.
"""

from __future__ import annotations

import codecs
import csv
import io
import itertools
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import DataError
from .measured import MissingColumn

DELIMITERS = (",", ";", "\t")
DECIMALS = (".", ",")
_SNIFF_ROWS = 20  # rows after the header that the delimiter must split like the header
_DECIMAL_COMMA = re.compile(r"^[+-]?\d*,\d+(?:[eE][+-]?\d+)?$")
_TIME_UNIT_WORDS = {"s": "s", "sec": "s", "ms": "ms", "msec": "ms", "us": "us", "usec": "us", "\u00b5s": "us",
                    "\u03bcs": "us"}


class SkippedRowWarning(UserWarning):
    """A CSV row that holds no sample (the units under the header) was skipped."""



def check_dialect(delimiter: str | None, decimal: str, source: str) -> None:
    """Refuse a CSV dialect that cannot be meant before a byte is read."""
    if delimiter is not None and delimiter not in DELIMITERS:
        raise DataError(f"delimiter {_toml(delimiter)} is not one of {_listing(DELIMITERS)} "
                        "(or none: detected)", source)
    if decimal not in DECIMALS:
        raise DataError(f"decimal separator {_toml(decimal)} is not one of {_listing(DECIMALS)}", source)
    if decimal == "," == delimiter:
        raise DataError("a decimal comma needs a delimiter other than \",\" (one comma cannot separate both fields "
                        f"and decimals); with it the delimiter is one of {_listing(DELIMITERS[1:])}", source)


@dataclass(frozen=True)
class CsvTable:
    """A CSV's samples as text, split by its dialect, with the file row of each: what the
    number reader and the PMU timestamp reader share."""

    source: str
    names: list[str]
    cells: np.ndarray  # (samples, columns), stripped text
    rows: np.ndarray  # file row of each sample, header = row 1
    delimiter: str
    decimal: str
    units: dict[str, str] = field(default_factory=dict)  # as a units row under the header states them
    units_row: int | None = None
    notes: tuple[str, ...] = ()

    def numbers(self, names: Sequence[str]) -> np.ndarray:
        """The named columns as float64 (an empty cell is NaN), converted at once; the first
        cell that is no number is refused by its row, column and value."""
        idx = [self.names.index(n) for n in names]
        text = self.cells[:, idx]
        if self.decimal == ",":
            dotted = np.argwhere(np.char.find(text, ".") >= 0)
            if dotted.size:
                i, j = dotted[0]
                raise DataError(f"column '{names[j]}': '{text[i, j]}' has a '.', but the decimal separator is ',': "
                                "a '.' there is a thousands separator or another export's number, which cannot be "
                                "told apart; export the numbers without it", self.source, int(self.rows[i]))
            text = np.char.replace(text, ",", ".")
        text = np.where(text == "", "nan", text)
        try:
            return text.astype(np.float64)
        except ValueError:
            i, j = _first_not_number(text)
        cell = str(self.cells[i, idx[j]])
        hint = ""
        if self.decimal == "." and self.delimiter != "," and _DECIMAL_COMMA.match(cell):
            hint = '; it reads as a decimal comma: set [data] decimal = ","'
        raise DataError(f"column '{names[j]}': '{cell}' is not a number (leave the cell empty or write nan for a "
                        f"missing sample){hint}", self.source, int(self.rows[i]))

    def check_time_unit(self, column: str, time_unit: str) -> None:
        """A time unit stated in the units row must be the one the time is read in: else
        every stamp would be off by a factor of 1000."""
        stated = self.units.get(column, "")
        unit = _TIME_UNIT_WORDS.get(stated.strip("[]() ").lower())
        if unit is not None and unit != time_unit:
            raise DataError(f"the units row gives column '{column}' in '{stated}', but it is read in "
                            f"'{time_unit}': set [data] time_unit = \"{unit}\"", self.source, self.units_row)


def read_csv_table(file: Path, source: str, required: str, delimiter: str | None = None, decimal: str = ".",
                   text_columns: Sequence[str] = ()) -> CsvTable:
    """The header and samples of a CSV, split by its delimiter (given, or detected), with
    a units row under the header skipped and said. ``required`` must be in the header;
    ``text_columns`` (timestamps) need not hold numbers."""
    check_dialect(delimiter, decimal, source)
    lines = _lines(file, source)
    start = next((i for i, line in enumerate(lines) if line.strip()), None)
    if start is None:
        raise DataError("the file is empty", source)
    if delimiter is None:
        delimiter = _detect_delimiter(lines, start, decimal, required, text_columns, source)
    names = _header(lines[start], start + 1, delimiter, required, source)
    records, rows = _records(lines, start + 1, delimiter, source)
    if not records:
        raise DataError("the file has a header but no samples", source)
    counts = np.fromiter(map(len, records), dtype=np.int64, count=len(records))
    wrong = np.flatnonzero(counts != len(names))
    if wrong.size:
        i = int(wrong[0])
        raise DataError(f"expected {len(names)} fields ({', '.join(names)}), found {counts[i]}: "
                        f"{lines[rows[i] - 1].rstrip(chr(13) + chr(10))!r}", source, rows[i])
    cells = np.char.strip(np.array(records, dtype=str))
    rows = np.asarray(rows, dtype=np.int64)
    numeric = np.array([n not in text_columns for n in names])
    if not _is_units_row(cells[0, numeric].tolist()):
        return CsvTable(source, names, cells, rows, delimiter, decimal)
    units = {n: u for n, u in zip(names, cells[0].tolist()) if u}
    said = ", ".join(f"{n} {u}" for n, u in units.items())
    if len(rows) == 1:
        raise DataError(f"the file has a header and units ({said}) but no samples", source)
    return CsvTable(source, names, cells[1:], rows[1:], delimiter, decimal, units, int(rows[0]),
                    (f"row {rows[0]} holds units ({said}), not a sample: skipped",))


def _lines(file: Path, source: str) -> list[str]:
    """The file's lines, their ends as written (the csv module reads CRLF), a UTF-8 BOM removed."""
    raw = file.read_bytes()
    skip = len(codecs.BOM_UTF8) if raw.startswith(codecs.BOM_UTF8) else 0
    try:
        text = raw[skip:].decode("utf-8")
    except UnicodeDecodeError as e:
        at = skip + e.start
        raise DataError(f"not UTF-8 text: byte 0x{raw[at]:02x} cannot be read; save the export as UTF-8", source,
                        raw.count(b"\n", 0, at) + 1) from None
    return io.StringIO(text, newline="").readlines()


def _header(line: str, row: int, delimiter: str, required: str, source: str) -> list[str]:
    names = [h.strip() for h in _split(line, delimiter)]
    for k, name in enumerate(names):
        if not name:
            raise DataError(f"column {k + 1} of the header has no name", source, row)
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise DataError(f"repeated column name(s) in the header: {', '.join(dupes)}", source, row)
    if required in names:
        return names
    others = [d for d in DELIMITERS if d != delimiter and len(_split(line, d)) > 1]
    if len(names) == 1 and others:  # a delimiter given that the file does not use
        raise DataError(f"the header is one column, '{names[0]}', split on {_shown(delimiter)}; it splits on "
                        f"{_shown(others[0])}: set [data] delimiter = {_toml(others[0])} (or leave it out to "
                        "detect it)", source, row)
    raise MissingColumn(required, [n for n in names if n != required], source)


def _records(lines: list[str], first: int, delimiter: str, source: str) -> tuple[list[list[str]], list[int]]:
    """The fields of each non-blank line after the first ``first``, and its file row."""
    reader = csv.reader(lines[first:], delimiter=delimiter)
    records, rows = [], []
    try:
        for record in reader:
            if len(record) > 1 or record and record[0].strip():
                records.append(record)
                rows.append(first + reader.line_num)
    except csv.Error as e:
        raise DataError(f"cannot be read as CSV: {e}", source, first + reader.line_num) from None
    return records, rows


def _detect_delimiter(lines: list[str], start: int, decimal: str, required: str, text_columns: Sequence[str],
                      source: str) -> str:
    """The delimiter that splits the header into columns and the first rows into as many.
    Where several do, the one whose header holds the time column is taken, then the one
    under which the rows are numbers; where that leaves several, the file is refused at
    its row rather than read wrong (a semicolon file with decimal commas can split evenly
    on commas too)."""
    sample = list(itertools.islice(((i + 1, lines[i]) for i in range(start, len(lines)) if lines[i].strip()),
                                   _SNIFF_ROWS + 1))
    allowed = [d for d in DELIMITERS if not d == "," == decimal]
    split = {d: [_split(line, d) for _, line in sample] for d in allowed}
    width = {d: len(split[d][0]) for d in allowed}
    splitting = [d for d in allowed if width[d] > 1]
    header_row, header = sample[0]
    if not splitting:
        if decimal == "," and len(_split(header, ",")) > 1:
            raise DataError("the header splits on ',' only, but with a decimal comma the delimiter is ';' or tab: "
                            "are the decimals points (leave [data] decimal out)?", source, header_row)
        return allowed[0]  # one column
    agree = {d: sum(len(r) == width[d] for r in split[d][1:]) for d in splitting}
    chosen = [d for d in splitting if agree[d] == max(agree.values())]
    chosen = _narrowed(chosen, lambda d: required in (c.strip() for c in split[d][0]))
    chosen = _narrowed(chosen, lambda d: _numbers_under(split[d], text_columns))
    if len(chosen) == 1:
        return chosen[0]
    k = 1 if len(sample) > 1 else 0
    readings = " and ".join(f"on {_shown(d)} ({' | '.join(c.strip() for c in split[d][k])})" for d in chosen)
    raise DataError(f"cannot tell the delimiter: this row and the header split alike {readings}; say which: "
                    f"[data] delimiter = {' or '.join(_toml(d) for d in chosen)}", source, sample[k][0])


def _split(line: str, delimiter: str) -> list[str]:
    try:
        return next(csv.reader([line], delimiter=delimiter), [])
    except csv.Error:
        return []


def _narrowed(options: list[str], test) -> list[str]:
    """The options that pass ``test``, or all of them if none does."""
    return [o for o in options if test(o)] or options


def _numbers_under(rows: list[list[str]], text_columns: Sequence[str]) -> bool:
    """Every cell under the header is a number (either decimal separator), text columns
    and a units row aside: what a wrong split breaks."""
    numeric = [k for k, n in enumerate(rows[0]) if n.strip() not in text_columns]
    body = [[r[k].strip() for k in numeric if k < len(r)] for r in rows[1:]]
    if body and _is_units_row(body[0]):
        body = body[1:]
    return all(_looks_numeric(c) for r in body for c in r if c)


def _is_units_row(cells: Sequence[str]) -> bool:
    """Text and no number: what a historian writes under the header (``s;Hz;MW``)."""
    texts = [c for c in cells if c]
    return bool(texts) and not any(_looks_numeric(c) for c in texts)


def _looks_numeric(cell: str) -> bool:
    try:
        float(cell.replace(",", "."))
    except ValueError:
        return False
    return True


def _first_not_number(text: np.ndarray) -> tuple[int, int]:
    """Row and column of the first cell ``float`` refuses (only when converting failed)."""
    for i, row in enumerate(text.tolist()):
        for j, cell in enumerate(row):
            try:
                float(cell)
            except ValueError:
                return i, j
    raise AssertionError("numpy refused a cell that float reads")


def _shown(delimiter: str) -> str:
    return "tab" if delimiter == "\t" else f"'{delimiter}'"


def _toml(text: str) -> str:
    return json.dumps(text)


def _listing(values: Sequence[str]) -> str:
    return ", ".join(map(_toml, values))


