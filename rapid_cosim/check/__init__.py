"""``rapid-cosim check PATH`` and ``rc.check``: everything a run would load, loaded and
checked before the run, and what the run will do.

PATH is an experiment config (a ``config.toml`` or its folder), a unit (``unit.toml`` or
its folder) or a fleet file. The check loads the configs and their recordings, the
structure files against their benches, the records on file, as the run would; it
reports every problem at once, each naming its file and key or row
(:class:`~rapid_cosim.errors.Finding`), a config's too (each mistake's key set aside and
the rest read again: :mod:`rapid_cosim.experiment.problems`), and says each recording's time base, what will
be estimated and in which stages, and about how many simulations and how long they take
on this machine (:mod:`.cost`). ``identify`` and ``fleet`` run the same checks before any
fit (:mod:`rapid_cosim.identify.check`, :mod:`rapid_cosim.fleet.check`).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from ..compiler.source import ModelSource
from .report import CheckReport, check_configs, check_fleet, check_unit_report

__all__ = ["CheckReport", "check", "kind_of"]


def kind_of(path: str | Path) -> tuple[str, Path]:
    """("config" | "unit" | "fleet", the file) of a path a user gives."""
    path = Path(path)
    if path.is_dir():
        for name, kind in (("fleet.toml", "fleet"), ("unit.toml", "unit"), ("config.toml", "config")):
            if (path / name).is_file():
                return kind, path / name
        return "config", path / "config.toml"  # the config loader names what is missing
    try:
        sections = set(tomllib.loads(path.read_text()))
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return "config", path
    if "fleet" in sections:
        return "fleet", path
    if sections & {"unit", "tests"} and not sections & {"experiment", "data"}:
        return "unit", path
    return "config", path


def check(path: str | Path, *, method: str = "pf:10+nm", source: ModelSource = ModelSource()) -> CheckReport:
    """Check what a run of ``path`` would load (module docstring); ``method``: the
    estimator chain a calibration of a config would run. A ``source`` whose package is
    not there raises, as every API call does (:meth:`ModelSource.check`)."""
    source.check()
    kind, file = kind_of(path)
    if kind == "fleet":
        return check_fleet(file, source=source)
    if kind == "unit":
        return check_unit_report(file, source=source)
    return check_configs([file], method=method, source=source)
