"""Every problem of a config at once, for ``check``: the readers stop at a config's first
mistake (a run must), so each mistake found is set aside, its key removed from the parsed
config, and the rest read again, until the config reads or a mistake has no key to set
aside (a missing file, a missing required key, the data's own problems).

A removal can itself cause an error (a table left empty, a required key gone); such an
error is the reading's, not the user's, and is not reported: the key it names is set
aside in turn where it is not a section, and the reading stops where it is."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from ..errors import ConfigError, RapidCosimError
from .config import load_experiment, parse_experiment
from .definition import CONFIG_NAME, Experiment
from .toml_writer import render_config

_PART = re.compile(r'"((?:[^"\\]|\\.)*)"|([^.]+)')
LIMIT = 50  # set-asides before giving up: far more mistakes than a config has keys to hold


def key_path(key: str) -> tuple[str, ...]:
    """A located key (``estimate."gov.R".min``) as its parts: quoted parts keep their dots."""
    return tuple(q if q else bare for q, bare in _PART.findall(key))


def every_problem(path: str | Path) -> tuple[Experiment | None, list[RapidCosimError]]:
    """The experiment a config describes, or every problem found in it, in reading order."""
    path = Path(path)
    if path.is_dir():
        path = path / CONFIG_NAME
    try:
        return load_experiment(path), []
    except ConfigError as e:
        error = e
    except RapidCosimError as e:
        return None, [e]
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None, [error]  # the file itself is the problem: nothing to set aside
    found: list[RapidCosimError] = [error]
    removed: list[tuple[str, ...]] = []
    for _ in range(LIMIT):
        target = key_path(error.key) if error.key else ()
        caused = any(_related(target, r) for r in removed)
        if caused:
            found.remove(error)
        if len(target) < (2 if caused else 1) or target in removed or not _remove(raw, target):
            break
        removed.append(target)
        try:
            parse_experiment(render_config(raw), path)
            break
        except ConfigError as e:
            error = e
            found.append(e)
        except RapidCosimError as e:
            found.append(e)
            break
        except ValueError:  # what is left cannot be written back as a config
            break
    return None, found


def _related(a: tuple[str, ...], b: tuple[str, ...]) -> bool:
    n = min(len(a), len(b))
    return n > 0 and a[:n] == b[:n]


def _remove(raw: dict, target: tuple[str, ...]) -> bool:
    table = raw
    for part in target[:-1]:
        table = table.get(part) if isinstance(table, dict) else None
        if not isinstance(table, dict):
            return False
    if target[-1] not in table:
        return False
    del table[target[-1]]
    return True
