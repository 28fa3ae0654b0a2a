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
estimates: they stay estimated, and the record's value is their ``start`` (the documented
value as the first guess) when it lies within their bounds and no start is given. The
record's iGrGen values are used as read (pu on the machine base; conversions in
:mod:`rapid_cosim.exchange.tables`).

Why the text is rewritten: the config is expanded once, when it is read, into the same
config with the record's values written out (and a comment naming the record, its line
and the values not taken). An archive stores that text, so a run is rebuilt, resumed and
re-run from the archive alone, without the record file. With starts taken from the
record, the ``[estimate]`` section is written anew (its own comments are not kept).
"""

from __future__ import annotations

import re
from pathlib import Path

from ..errors import ConfigError, RapidCosimError
from ..exchange import Record, read_record
from .toml_writer import dotted_items, render_config

KEY = "documented"
PREFIX = "gov."


def record_constants(value, fixed: dict, estimate: dict, folder: Path, file: str,
                     key: str = f"fixed.{KEY}") -> tuple[Record, dict[str, float], dict[str, float], list[str]]:
    """The record named by ``value`` (relative to ``folder``), the ``gov.*`` values it
    adds to ``fixed``, the starts it gives estimated parameters, and a note per value
    not taken as a constant."""
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(f"expected the name of a .dyr or .dyd record file, got {value!r}", file, key)
    path = Path(value) if Path(value).is_absolute() else folder / value
    try:
        record = read_record(path)
    except RapidCosimError as e:
        raise ConfigError(str(e), file, key) from None
    stated, specs = set(_names(fixed, _is_value)) - {KEY}, dict(dotted_items(estimate, _is_spec))
    added, starts, notes = {}, {}, []
    for param, v in record.values.items():
        name = PREFIX + param
        spec = specs.get(name)
        if name in stated:
            notes.append(f"{name}: {v!r} in the record, the value stated here kept")
        elif spec is None:
            added[name] = v
        elif not isinstance(spec, dict) or "start" in spec:
            notes.append(f"{name}: {v!r} in the record, estimated here from the start given")
        elif isinstance(spec.get("min"), (int, float)) and isinstance(spec.get("max"), (int, float)) \
                and spec["min"] <= v <= spec["max"]:
            notes.append(f"{name}: {v!r} in the record, estimated here from it")
            starts[name] = v
        else:
            notes.append(f"{name}: {v!r} in the record, outside the range estimated: not a start")
    return record, added, starts, notes


def expand(text: str, raw: dict, path: Path) -> str:
    """``text`` with its ``documented = "..."`` line of ``[fixed]`` replaced by the
    record's values (unchanged when there is none)."""
    fixed = raw.get("fixed")
    if not isinstance(fixed, dict) or KEY not in fixed:
        return text
    file = str(path)
    estimate = raw.get("estimate", {}) or {}
    record, added, starts, notes = record_constants(fixed[KEY], fixed, estimate, path.parent, file)
    lines = [f"# documented constants from {fixed[KEY]!r}: {record.model} of machine {record.machine_id} at bus "
             f"{record.bus} ({record.file}, line {record.line})"]
    lines += [f"# {note}" for note in notes]
    lines += [f'"{name}" = {value!r}' for name, value in added.items()]
    _, start, end = _section(text, "fixed")
    line = re.compile(rf"^[ \t]*{KEY}[ \t]*=[ \t]*(\"[^\"\n]*\"|'[^'\n]*')[ \t]*(#[^\n]*)?$", re.M)
    found = list(line.finditer(text, start, end))
    if len(found) != 1:
        raise ConfigError(f"write {KEY} = \"file\" on a line of its own in [fixed]", file, f"fixed.{KEY}")
    m = found[0]
    text = text[:m.start()] + "\n".join(lines) + text[m.end():]
    if starts:
        head, _, end = _section(text, "estimate")
        specs = {name: {**spec, "start": starts[name]} if name in starts else spec
                 for name, spec in dotted_items(estimate, _is_spec)}
        block = f"# [estimate] written out with starts from {fixed[KEY]!r}\n" + render_config({"estimate": specs}) + "\n"
        text = text[:head] + block + text[end:]
    return text


def _section(text: str, name: str) -> tuple[int, int, int]:
    """Where ``[name]`` starts, where its body starts and where it ends."""
    head = re.search(rf"^[ \t]*\[{name}\][ \t]*(#[^\n]*)?$", text, re.M)
    if head is None:
        return 0, 0, 0
    nxt = re.compile(r"^[ \t]*\[", re.M).search(text, head.end())
    return head.start(), head.end(), nxt.start() if nxt else len(text)


def _is_value(v) -> bool:
    return not isinstance(v, dict)


def _is_spec(v) -> bool:
    return not isinstance(v, dict) or not v or "min" in v or "max" in v


def _names(table: dict, is_leaf):
    return (name for name, _ in dotted_items(table, is_leaf))
