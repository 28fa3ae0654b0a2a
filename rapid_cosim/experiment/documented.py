"""A config's documented constants taken from the grid simulators' record of the unit.

A unit's governor constants usually arrive as a PSS/E ``.dyr`` or PSLF ``.dyd`` record
(:mod:`rapid_cosim.exchange`). Rather than copying them into ``[fixed]`` by hand, a config
(or a structure file) names the record::

    [fixed]
    documented = "unit.dyr"      # relative to the config's folder
    "gov.p_ref" = 0.6            # stated values win over the record's
    "src.df" = -0.2

Every parameter the record carries becomes ``"gov.<name>" = value`` in ``[fixed]``, except
those the config states itself in ``[fixed]`` (the stated value is kept) and those it
estimates (they stay estimated). The record's iGrGen values are used as read (pu on the
machine base; conversions in :mod:`rapid_cosim.exchange.tables`).

Why the text is rewritten: the config is expanded once, when it is read, into the same
config with the record's values written out (and a comment naming the record, its line
and the values not taken). An archive stores that text, so a run is rebuilt, resumed and
re-run from the archive alone, without the record file.
"""

from __future__ import annotations

import re
from pathlib import Path

from ..errors import ConfigError, RapidCosimError
from ..exchange import Record, read_record

KEY = "documented"
PREFIX = "gov."


def record_constants(value, fixed: dict, estimate: dict, folder: Path, file: str,
                     key: str = f"fixed.{KEY}") -> tuple[Record, dict[str, float], list[str]]:
    """The record named by ``value`` (relative to ``folder``), the ``gov.*`` values it
    adds to ``fixed``, and a note per value not taken."""
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"expected the name of a .dyr or .dyd record file, got {value!r}", file, key)
    path = Path(value) if Path(value).is_absolute() else folder / value
    try:
        record = read_record(path)
    except RapidCosimError as e:
        raise ConfigError(str(e), file, key) from None
    stated, estimated = set(_names(fixed, _is_value)) - {KEY}, set(_names(estimate, _is_spec))
    added, notes = {}, []
    for param, v in record.values.items():
        name = PREFIX + param
        if name in stated:
            notes.append(f"{name}: {v!r} in the record, the value stated here kept")
        elif name in estimated:
            notes.append(f"{name}: {v!r} in the record, estimated here")
        else:
            added[name] = v
    return record, added, notes


def expand(text: str, raw: dict, path: Path) -> str:
    """``text`` with its ``documented = "..."`` line of ``[fixed]`` replaced by the
    record's values (unchanged when there is none)."""
    fixed = raw.get("fixed")
    if not isinstance(fixed, dict) or KEY not in fixed:
        return text
    file = str(path)
    record, added, notes = record_constants(fixed[KEY], fixed, raw.get("estimate", {}) or {}, path.parent, file)
    lines = [f"# documented constants from {fixed[KEY]!r}: {record.model} of machine {record.machine_id} at bus "
             f"{record.bus} ({record.file}, line {record.line})"]
    lines += [f"# {note}" for note in notes]
    lines += [f'"{name}" = {value!r}' for name, value in added.items()]
    start, end = _section(text, "fixed")
    line = re.compile(rf"^[ \t]*{KEY}[ \t]*=[ \t]*(\"[^\"\n]*\"|'[^'\n]*')[ \t]*(#[^\n]*)?$", re.M)
    found = list(line.finditer(text, start, end))
    if len(found) != 1:
        raise ConfigError(f"write {KEY} = \"file\" on a line of its own in [fixed]", file, f"fixed.{KEY}")
    m = found[0]
    return text[:m.start()] + "\n".join(lines) + text[m.end():]


def _section(text: str, name: str) -> tuple[int, int]:
    head = re.search(rf"^[ \t]*\[{name}\][ \t]*(#[^\n]*)?$", text, re.M)
    if head is None:
        return 0, 0
    nxt = re.compile(r"^[ \t]*\[", re.M).search(text, head.end())
    return head.end(), nxt.start() if nxt else len(text)


def _is_value(v) -> bool:
    return not isinstance(v, dict)


def _is_spec(v) -> bool:
    return not isinstance(v, dict) or not v or "min" in v or "max" in v


def _names(table: dict, is_leaf, prefix: str = ""):
    for k, v in table.items():
        name = f"{prefix}.{k}" if prefix else k
        if is_leaf(v):
            yield name
        else:
            yield from _names(v, is_leaf, name)
