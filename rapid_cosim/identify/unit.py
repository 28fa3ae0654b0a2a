"""A unit folder: one ``unit.toml`` naming a unit's staged tests and recorded events, the
held-out choices, the standard structures its record may take, and where the record goes
in the grid operator's case::

    [unit]
    name = "Unit 1"
    kind = "steam"          # steam, gas or hydro: the standard structures it gets by default
    mva = 400.0             # the machine's MVA base: a PSLF .dyd record needs it (optional)
    bus = 1                 # where the record goes in the grid operator's case
    machine_id = "1"

    [tests]                 # experiment configs (folders or config.toml), relative to this file:
    configs = ["test1", "test2", "event1"]   # staged tests, recorded events (CSV, COMTRADE, PMU CSV)
    holdout = ["test2"]     # names of experiments kept out of the fits to confirm the verdict

    [structures]            # the structures a record may take (optional, see below)
    files = ["structures/TGOV1.toml"]   # structure files, relative to this file
    standard = ["IEEEG1"]               # and/or the shipped standard ones, by name

Without ``[structures]``, a unit gets the shipped standard structures of its kind
(:mod:`rapid_cosim.structures.shipped`: steam TGOV1 and IEEEG1, gas GAST and GGOV1,
hydro HYGOV); a unit of no stated kind gets its own ``structures/<name>.toml`` of the
standard names where it has that folder (as units made before the kinds had), else every
shipped standard structure.

The tests' configs hold the documented constants of TG Type I (the explanation's base);
each structure file holds its own (given directly or as ``documented = "unit.dyr"``, a
PSS/E or PSLF record of the unit, see :mod:`rapid_cosim.exchange`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..data import close_matches
from ..errors import ConfigError
from ..experiment.reader import load_toml
from ..experiment.schema import UNIT_FILE
from ..structures.shipped import STANDARD_FILES, kind_files, standard_file

MVA_RANGE = (1.0, 5000.0)
KEYS = UNIT_FILE.accepted()  # section -> its keys, as docs/config.md lists them


def check_mva(mva, source: str | None = None, key: str | None = None, *, given: str = "") -> float:
    """The machine's MVA base as a float, refused outside 1 to 5000 MVA (a PSLF .dyd record
    states it; a typo of a factor 1000 would scale every MW-based constant). ``given``:
    where the value came from, when not a file's key."""
    lo, hi = MVA_RANGE
    if isinstance(mva, bool) or not isinstance(mva, (int, float)) or not lo <= mva <= hi:
        raise ConfigError(f"mva = {mva!r}{given}: the machine's MVA base, a number from {lo:g} to {hi:g}",
                          source, key)
    return float(mva)


NO_HOLDOUT = ("no test is held out ([tests] holdout): every fidelity figure is then on the tests the records "
              "were fitted to, and nothing shows that a record predicts a test it was not fitted to; hold out "
              "one test of each kind where the unit has three or more")


@dataclass(frozen=True)
class Unit:
    name: str
    mva: float | None  # None: no .dyd record (it states the base; a .dyr takes it from the .raw)
    bus: int
    machine_id: str
    configs: tuple[Path, ...]
    holdout: tuple[str, ...]
    structures: tuple[Path, ...]
    path: Path
    kind: str | None = None  # steam, gas, hydro: the standard structures by default

    @classmethod
    def load(cls, path: str | Path) -> "Unit":
        path = Path(path)
        if path.is_dir():
            path = path / "unit.toml"
        raw, _ = load_toml(path, "the unit file")
        for section, keys in KEYS.items():
            if not isinstance(raw.get(section, {}), dict):
                raise ConfigError(f"[{section}] must be a table (a section), got {raw[section]!r}", str(path), section)
            unknown = sorted(set(raw.get(section, {})) - keys)
            if unknown:
                close = close_matches(unknown[0], sorted(keys), n=1)
                raise ConfigError(f"unknown key '{unknown[0]}'" + (f" (did you mean '{close[0]}'?)" if close else "")
                                  + f"; allowed: {', '.join(sorted(keys))}", str(path), f"{section}.{unknown[0]}")
        extra = sorted(set(raw) - set(KEYS))
        if extra:
            raise ConfigError(f"unknown section(s) {', '.join(extra)}; allowed: {', '.join(KEYS)}", str(path))
        head, tests = raw.get("unit", {}), raw.get("tests", {})
        mva = head.get("mva")
        if mva is not None:
            mva = check_mva(mva, str(path), "unit.mva")
        bus = head.get("bus", 1)
        if isinstance(bus, bool) or not isinstance(bus, int) or not 1 <= bus <= 999999:
            raise ConfigError(f"bus = {bus!r}: a bus number from 1 to 999999", str(path), "unit.bus")
        configs = tests.get("configs")
        if not isinstance(configs, list) or not configs or not all(isinstance(c, str) for c in configs):
            raise ConfigError("configs must list the unit's experiment configs (folders or config.toml files)",
                              str(path), "tests.configs")
        folder = path.parent
        found = []
        for c in configs:
            p = folder / c
            p = p / "config.toml" if p.is_dir() else p
            if not p.is_file():
                raise ConfigError(f"{c}: no such experiment config ({p})", str(path), "tests.configs")
            found.append(p)
        kind = head.get("kind")
        if kind is not None and not isinstance(kind, str):
            raise ConfigError(f"kind = {kind!r}: steam, gas or hydro", str(path), "unit.kind")
        files = _structure_files(raw.get("structures"), folder, kind, str(path))
        holdout = tests.get("holdout", [])
        if not isinstance(holdout, list) or not all(isinstance(h, str) for h in holdout):
            raise ConfigError("holdout must list experiment names", str(path), "tests.holdout")
        return cls(str(head.get("name", folder.name)), mva, bus,
                   str(head.get("machine_id", "1")), tuple(found), tuple(holdout), tuple(files), path, kind)


def _structure_files(section: dict | None, folder: Path, kind: str | None, where: str) -> list[Path]:
    """The unit's structure files: those ``[structures]`` lists (``files`` relative to the
    unit file, ``standard`` by name), else those of its kind (module docstring)."""
    if kind is not None:
        defaults = kind_files(kind, where=where, key="unit.kind")
    else:
        own = [folder / "structures" / f"{s}.toml" for s in STANDARD_FILES]
        defaults = [p for p in own if p.is_file()] or kind_files(None)
    if section is None:
        return defaults
    listed, named = section.get("files", []), section.get("standard", [])
    for key, value in (("files", listed), ("standard", named)):
        if not isinstance(value, list) or not all(isinstance(f, str) for f in value):
            example = '["structures/TGOV1.toml"]' if key == "files" else '["TGOV1", "IEEEG1"]'
            raise ConfigError(f"{key} must list {'structure files' if key == 'files' else 'standard structures'}, "
                              f"e.g. {example}, got {value!r}", where, f"structures.{key}")
    files = [folder / f for f in listed] + [standard_file(n, where=where, key="structures.standard") for n in named]
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise ConfigError(f"no such structure file: {', '.join(missing)} (the shipped standard ones are named by "
                          f"[structures] standard = [...], or by [unit] kind)", where, "structures.files")
    return files or defaults
