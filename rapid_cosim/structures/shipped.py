"""The standard structure files that ship with rapid-cosim (``standard/*.toml``), and
which of them a unit gets by its kind of plant when its ``unit.toml`` names none.

Why here: a unit folder made from scratch (or from an installed wheel, with no clone to
copy ``structures/`` from) still gets the structures of its plant, each with the optional
parts the data may call for (IEEEG1's valve rates, the deadbands).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ..errors import ConfigError

# the standard structures of each kind of plant, the richer last
KINDS: dict[str, tuple[str, ...]] = {
    "steam": ("TGOV1", "IEEEG1"),
    "gas": ("GAST", "GGOV1"),
    "hydro": ("HYGOV",),
}
STANDARD_FILES = ("TGOV1", "IEEEG1", "GGOV1", "HYGOV", "GAST")  # a unit of no stated kind: every one


def standard_file(name: str, *, where: str | None = None, key: str | None = None) -> Path:
    """The shipped structure file of ``name`` (``TGOV1``, ... or ``TGTypeI``)."""
    path = Path(str(resources.files("rapid_cosim.structures") / "standard" / f"{name}.toml"))
    if not path.is_file():
        names = sorted(p.stem for p in path.parent.glob("*.toml"))
        raise ConfigError(f"no standard structure {name!r}; shipped: {', '.join(names)}", where, key)
    return path


def kind_files(kind: str | None, *, where: str | None = None, key: str | None = None) -> list[Path]:
    """The shipped structure files of a kind of plant (None: every standard one)."""
    if kind is None:
        return [standard_file(n) for n in STANDARD_FILES]
    if kind not in KINDS:
        raise ConfigError(f"kind = {kind!r}: the kind of plant is one of {', '.join(KINDS)}", where, key)
    return [standard_file(n) for n in KINDS[kind]]
