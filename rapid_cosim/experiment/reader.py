"""Typed access to a parsed config, every mistake a :class:`ConfigError` naming the file
and the key: what each section's reader (:mod:`.spec`, :mod:`.signals`, :mod:`.recording`,
:mod:`.electrical`, :mod:`.recorder`) is handed as ``cfg``."""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path
from typing import Sequence

from ..data import close_matches
from ..errors import ConfigError
from .toml_writer import config_key


class ConfigReader:
    """Typed access to parsed TOML that raises ConfigError naming file and key."""

    def __init__(self, file: str):
        self.file = file

    def check_keys(self, table: dict, known: frozenset[str], where: str) -> None:
        for k in table:
            if k not in known:
                what = f"top-level key '{k}'" if not where else f"key '{k}'"
                raise ConfigError(f"unknown {what}{suggest(k, sorted(known))}; allowed: "
                                  f"{', '.join(sorted(known))}", self.file, config_key(where, k))

    def table(self, value, key: str) -> dict:
        if not isinstance(value, dict):
            raise ConfigError(f"expected a table, got {value!r}", self.file, key)
        return value

    def require(self, table: dict, where: str, k: str):
        if k not in table:
            raise ConfigError(f"missing required key '{k}'", self.file, config_key(where, k))
        return table[k]

    def string(self, table: dict, where: str, k: str, default: str | None = None,
               allow_empty: bool = False) -> str:
        value = self.require(table, where, k) if default is None else table.get(k, default)
        if not isinstance(value, str) or not (value.strip() or allow_empty):
            raise ConfigError(f"expected a non-empty string, got {value!r}", self.file, config_key(where, k))
        return value

    def boolean(self, table: dict, where: str, k: str, default: bool) -> bool:
        value = table.get(k, default)
        if not isinstance(value, bool):
            raise ConfigError(f"expected true or false, got {value!r}", self.file, config_key(where, k))
        return value

    def number(self, value, key: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"expected a number, got {value!r}", self.file, key)
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f"expected a finite number, got {value}", self.file, key)
        return value

    def parameter_name(self, name: str, key: str) -> None:
        if "@" in name or not name.strip():
            raise ConfigError(f"'{name}' is not a parameter name ('@' is reserved for "
                              f"per-experiment dimensions)", self.file, key)


def positive(value: float, cfg: ConfigReader, key: str) -> float:
    if not value > 0:
        raise ConfigError(f"must be positive, got {value:g}", cfg.file, key)
    return value


def suggest(word: str, candidates: Sequence[str]) -> str:
    close = close_matches(word, list(candidates))
    return f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""


def toml_message(e: tomllib.TOMLDecodeError, text: str) -> str:
    """TOML's complaint, the line it names, and what the mistake probably is: a decimal
    comma, or a data file given where a TOML file belongs."""
    message = f"invalid TOML: {e}"
    m = re.search(r"at line (\d+)", str(e))
    lines = text.splitlines()
    if m:
        n = int(m.group(1))
        if 1 <= n <= len(lines):
            message += f"\n    {n} | {lines[n - 1]}"
            if _DECIMAL_COMMA.search(lines[n - 1]):
                message += "\n    a decimal comma: TOML numbers take a point (400.0, not 400,0)"
    first = next((line for line in lines if line.strip()), "")
    if "=" not in first and not first.lstrip().startswith(("[", "#")) and _CSV_HEADER.search(first):
        message += ("\n    this looks like a data file (a header of columns), not a TOML file: give the config "
                    "that names it in [data] file")
    return message


_DECIMAL_COMMA = re.compile(r"=\s*-?\d+,\d+\s*(#.*)?$")
_CSV_HEADER = re.compile(r"^[^=]+[,;\t][^=]+$")


def load_toml(path: Path, what: str) -> tuple[dict, str]:
    """A TOML file's table and text; an unreadable or invalid one is a ConfigError naming
    ``what`` it should have been (``the unit file``) and, where TOML says, the line."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ConfigError(f"cannot read {what}: {e.strerror or e}", str(path)) from None
    except UnicodeDecodeError as e:
        raise ConfigError(f"{what} is not UTF-8 text: {e}", str(path)) from None
    try:
        return tomllib.loads(text), text
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(toml_message(e, text), str(path)) from None
