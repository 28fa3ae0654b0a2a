"""The examples that ship with rapid-cosim (``rapid-cosim example NAME [DIR]``,
``rc.example(NAME)``): the repository's ``experiments/`` folder travels inside the package
(``data``, a link to it), and an example is copied out of it into a folder of the user's,
whole and self-contained, so that every command of the README runs in an empty folder
after a ``pip install``.

What an example's unit names outside its own folder (the steam unit's structure files,
shared with the electrical unit) is copied in beside it, and its ``unit.toml`` names the
copy. The scripts that made the synthetic examples (``generate.py``, which need ANDES)
stay in the repository."""

from __future__ import annotations

import re
import shutil
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from ..errors import ConfigError

_STAGED = tuple(f"test{k}" for k in range(1, 11))


@dataclass(frozen=True)
class Example:
    parts: tuple[str, ...]  # folders and files of experiments/ that make it up
    what: str
    try_it: str  # the first command to run on it, from the folder it was copied into

    def folder(self, name: str) -> bool:
        """Whether the example is one folder of experiments/ (copied as DIR itself)."""
        return self.parts == (name,)


EXAMPLES: dict[str, Example] = {
    "test1": Example(("test1",), "staged test 1 of the field unit (MCR 60 %, -200 mHz): the README's first "
                     "calibration", "rapid-cosim estimate test1 --method pf:10+nm --seed 1"),
    "staged-tests": Example((*_STAGED, "unit.toml", "staged_tests.md", "structures"), "the field unit's ten "
                            "staged tests with its documentation and unit.toml (tests 4 and 8 held out)",
                            "rapid-cosim identify staged-tests/unit.toml"),
    "event1": Example(("event1",), "a recorded grid disturbance as a COMTRADE file (the frequency drives the "
                      "bench)", "rapid-cosim estimate event1"),
    "electrical": Example(("electrical",), "a unit from two ANDES grid events recorded as electrical power",
                          "rapid-cosim identify electrical/unit.toml"),
    "steam": Example(("steam",), "a steam unit with a binding opening rate (ANDES IEEEG1), three events on "
                     "regular stamps", "rapid-cosim identify steam/unit.toml"),
    "gas": Example(("gas",), "a gas turbine (ANDES GAST), three events; the shipped gas structures",
                   "rapid-cosim identify gas/unit.toml"),
    "deadband": Example(("deadband",), "a steam unit with a 36 mHz deadband (ANDES TGOV1DB), events of two sizes",
                        "rapid-cosim identify deadband/unit.toml"),
    "fleet": Example(("fleet",), "five synthetic units on one grid event, each with a record on file",
                     "rapid-cosim fleet fleet/fleet.toml"),
}
_SKIP = shutil.ignore_patterns("*.py", "__pycache__")
_FILES = re.compile(r'"((?:\.\./)+[^"]+)"')


def examples_root() -> Path:
    return Path(str(resources.files("rapid_cosim.examples") / "data"))


def copy_example(name: str, dest: str | Path | None = None) -> tuple[Path, bool]:
    """``name`` copied into ``dest`` (default ``./NAME``): the folder, and whether it was
    copied now (False: the folder was there already, and is left as it is)."""
    if name not in EXAMPLES:
        raise ConfigError(f"no example {name!r}; the examples: {', '.join(EXAMPLES)}")
    example, root = EXAMPLES[name], examples_root()
    dest = Path(dest) if dest is not None else Path(name)
    if dest.exists() and not dest.is_dir():
        raise ConfigError(f"{dest} is a file: give a folder to copy example {name!r} into")
    if dest.is_dir() and any(dest.iterdir()):
        return dest, False
    dest.mkdir(parents=True, exist_ok=True)
    if example.folder(name):
        shutil.copytree(root / name, dest, ignore=_SKIP, dirs_exist_ok=True)
    else:
        for part in example.parts:
            src = root / part
            if src.is_dir():
                shutil.copytree(src, dest / part, ignore=_SKIP)
            else:
                shutil.copy2(src, dest / part)
    _bring_in(dest, root / name if example.folder(name) else root)
    return dest, True


def _bring_in(dest: Path, origin: Path) -> None:
    """Each file a copied unit.toml names outside its folder, copied into its
    ``structures/`` and the unit.toml pointed at the copy."""
    for unit in dest.rglob("unit.toml"):
        text = unit.read_text(encoding="utf-8")
        here = origin / unit.parent.relative_to(dest)
        for outside in sorted(set(_FILES.findall(text))):
            target = unit.parent / "structures" / Path(outside).name
            target.parent.mkdir(exist_ok=True)
            shutil.copy2(here / outside, target)
            text = text.replace(f'"{outside}"', f'"structures/{Path(outside).name}"')
        unit.write_text(text, encoding="utf-8")
