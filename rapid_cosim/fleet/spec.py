"""A fleet file: the units of one grid event, and each one's record on file::

    [fleet]
    name = "Area 3, the 2026-11-20 under-frequency event"
    units = ["units/*"]          # unit folders (each with its unit.toml), or globs of them
    records = "records.dyr"      # optional: the units' records on file, one PSS/E .dyr or PSLF
                                 # .dyd holding them all, each unit's found by its bus and id
    tolerances = "bands.toml"    # optional: the validation bands (validation.tolerances)

A unit folder may also hold its own record on file, ``record.dyr`` or ``record.dyd``,
which comes before the fleet's. A unit with no record on file is identified. Paths are
relative to the fleet file. The units' configs name their recordings, and may share one
event's (the grid frequency, say) by a relative path.
"""

from __future__ import annotations

import glob
from dataclasses import dataclass
from pathlib import Path

from ..errors import ConfigError
from ..experiment.reader import load_toml
from ..experiment.schema import FLEET_FILE

KEYS = FLEET_FILE.accepted()["fleet"]  # as docs/config.md lists them
OWN_RECORDS = ("record.dyr", "record.dyd")


@dataclass(frozen=True)
class UnitEntry:
    """One unit of the fleet: its folder, and where its record on file is (None: none)."""

    name: str
    folder: Path
    record: Path | None


@dataclass(frozen=True)
class FleetSpec:
    name: str
    path: Path
    units: tuple[UnitEntry, ...]
    tolerances: Path | None


def load_fleet(path: str | Path) -> FleetSpec:
    """The fleet file, its globs expanded (sorted, each unit once); every mistake a
    :class:`ConfigError` naming the file and key."""
    path = Path(path)
    if path.is_dir():
        path = path / "fleet.toml"
    file = str(path)
    raw, _ = load_toml(path, "the fleet file")
    extra = sorted(set(raw) - {"fleet"})
    if extra or "fleet" not in raw:
        raise ConfigError(f"a fleet file has one section, [fleet]; found {', '.join(extra) or 'none'}", file)
    head = raw["fleet"]
    unknown = sorted(set(head) - KEYS)
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(unknown)}; allowed: {', '.join(sorted(KEYS))}", file, "fleet")
    patterns = head.get("units")
    if not isinstance(patterns, list) or not patterns or not all(isinstance(p, str) for p in patterns):
        raise ConfigError("units must be a list of unit folders or globs, e.g. [\"units/*\"]", file, "fleet.units")
    base = path.parent
    folders: list[Path] = []
    for pattern in patterns:
        found = sorted(Path(p) for p in glob.glob(str(base / pattern)))
        found = [f for f in found if (f / "unit.toml").is_file() or f.name == "unit.toml"]
        if not found:
            raise ConfigError(f"{pattern!r} names no unit folder (a folder with a unit.toml)", file, "fleet.units")
        folders += [f.parent if f.name == "unit.toml" else f for f in found]
    folders = list(dict.fromkeys(f.resolve() for f in folders))
    names = [f.name for f in folders]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ConfigError(f"two unit folders share the name {', '.join(twice)}: a fleet's results are filed by it",
                          file, "fleet.units")
    shared = _file(head, "records", base, file)
    units = []
    for folder in folders:
        own = next((folder / r for r in OWN_RECORDS if (folder / r).is_file()), None)
        units.append(UnitEntry(folder.name, folder, own or shared))
    name = head.get("name", path.parent.name)
    if not isinstance(name, str) or not name.strip():
        raise ConfigError(f"name must be a non-empty string, got {name!r}", file, "fleet.name")
    return FleetSpec(name, path.resolve(), tuple(units), _file(head, "tolerances", base, file))


def _file(head: dict, key: str, base: Path, file: str) -> Path | None:
    if key not in head:
        return None
    value = head[key]
    if not isinstance(value, str):
        raise ConfigError(f"{key} must be a file name, got {value!r}", file, f"fleet.{key}")
    target = (base / value).resolve()
    if not target.is_file():
        raise ConfigError(f"{key}: no file {target}", file, f"fleet.{key}")
    return target
