"""Configs that programs write (synthetic studies, the discrepancy workflow, experiments
made in code): ``{section: {key: value}}`` -> TOML text the reader accepts."""

from __future__ import annotations

import math
import re
from typing import Any, Mapping

import numpy as np

BARE_KEY_RE = re.compile(r"^[A-Za-z0-9_\-]+$")


def config_key(where: str, k: str) -> str:
    """`where.k` in TOML dotted-key form, quoting `k` when it is not a bare key."""
    part = k if BARE_KEY_RE.match(k) else f'"{k}"'
    return f"{where}.{part}" if where else part


def render_config(sections: Mapping[str, Mapping[str, Any]]) -> str:
    """TOML text of a config given as ``{section: {key: value}}``, for configs that
    programs write (synthetic studies, the discrepancy workflow's re-calibration).

    Values may be strings, booleans, numbers, lists of numbers, or tables of those
    (written inline); keys with dots are quoted.
    """
    lines: list[str] = []
    for section, table in sections.items():
        lines.append(f"[{section}]")
        for key, value in table.items():
            lines.append(f"{_toml_key(key)} = {_toml_value(value)}")
        lines.append("")
    return "\n".join(lines)


def _toml_key(key: str) -> str:
    return key if BARE_KEY_RE.match(key) else '"' + key.replace('"', '\\"') + '"'


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float, np.floating, np.integer)):
        v = float(value)
        if not math.isfinite(v):
            raise ValueError(f"cannot write non-finite number {v} to a config")
        return repr(int(value)) if isinstance(value, (int, np.integer)) else repr(v)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise ValueError(f"cannot write {type(value).__name__} to a config")


def dotted_items(table: dict, is_leaf, prefix: str = ""):
    """(dotted name, value) of each leaf of a parsed table: unquoted dotted keys
    (``gov.R = 0.05``) parse as nested tables, and configs name parameters by the dots."""
    for k, v in table.items():
        name = f"{prefix}.{k}" if prefix else k
        if is_leaf(v):
            yield name, v
        else:
            yield from dotted_items(v, is_leaf, name)
