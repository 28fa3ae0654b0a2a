"""Provenance of a validation report: what it was computed from, so a reader can tell
whether a file in front of them is the one that was validated. SHA-256 of every data
file the experiments name (and of the archived copy the report actually used), of the
archive, and the versions of the packages that computed it."""

from __future__ import annotations

import hashlib
import platform
import tomllib
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Sequence

from ..archive import RunArchive
from ..experiment import Experiment

PACKAGES = ("rapid-cosim", "fmpy", "numpy", "scipy", "casadi", "h5py", "matplotlib", "comtrade")
COMPANIONS = {".cfg": (".dat", ".hdr", ".inf"), ".CFG": (".DAT", ".HDR", ".INF")}  # COMTRADE's other files


@dataclass(frozen=True)
class FileDigest:
    experiment: str
    path: str
    sha256: str | None  # None: not on disk where the config says (the archived copy was used)


@dataclass(frozen=True)
class Provenance:
    archive: str
    archive_sha256: str
    archived_data: dict[str, str]  # the archive's own digest of each experiment's data, by key
    files: tuple[FileDigest, ...]
    versions: dict[str, str]
    python: str


def sha256(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def data_files(exp: Experiment) -> list[Path]:
    """The files an experiment's config names: ``[data] file``, the inputs' own files, and
    a COMTRADE header's companions that exist beside it."""
    try:
        doc = tomllib.loads(exp.config_text)
    except tomllib.TOMLDecodeError:
        return []
    names = [doc.get("data", {}).get("file")]
    names += [spec.get("file") for spec in doc.get("inputs", {}).values() if isinstance(spec, dict)]
    folder = Path(exp.config_path).parent
    out: list[Path] = []
    for name in dict.fromkeys(n for n in names if isinstance(n, str)):
        path = folder / name
        out.append(path)
        out += [c for c in (path.with_suffix(s) for s in COMPANIONS.get(path.suffix, ())) if c.exists()]
    return out


def provenance(archive: str | Path, experiments: Sequence[Experiment]) -> Provenance:
    files = []
    for exp in experiments:
        for path in data_files(exp):
            files.append(FileDigest(exp.name, str(path), sha256(path) if path.is_file() else None))
    with RunArchive(archive) as view:
        archived = dict(view.hashes["data"])
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return Provenance(str(archive), sha256(archive), archived, tuple(files), versions,
                      f"{platform.python_implementation()} {platform.python_version()} on {platform.platform()}")
