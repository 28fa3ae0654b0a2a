"""An FMU file -> a checked, extracted model: what the simulator needs to know of it.

Any FMI 2.0 Model Exchange FMU is accepted, whoever built it. It is checked once, on
load, with one clear error per problem: the FMI version, a Model Exchange interface, a
binary for this platform, and variables a run cannot drive (non-Real inputs or
parameters, String outputs) are refused by name when they are asked for.

:class:`FmuRef` carries an FMU by content, so that it can travel to other processes or
machines and be archived; :func:`load_fmu` keeps one extracted copy per FMU and process
(the package's only global state).
"""

from __future__ import annotations

import difflib
import hashlib
import math
import os
import shutil
import tempfile
import weakref
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from stat import S_ISREG
from typing import Mapping, Sequence

import fmpy
from fmpy import extract, read_model_description

from ..errors import FmuError, ParameterError

# How the runner reads an output of each FMI type (see runner.c).
OUTPUT_TYPES = {"Real": 0, "Integer": 1, "Enumeration": 1, "Boolean": 2}


@dataclass(frozen=True)
class ParameterInfo:
    """A parameter as the FMU's model description declares it (None: not declared)."""

    name: str
    start: float | None = None
    min: float | None = None
    max: float | None = None
    unit: str = ""
    description: str = ""
    settable: bool = True  # False for calculated parameters and non-Real ones
    type: str = "Real"


@dataclass(frozen=True)
class FmuRef:
    """An FMU that can travel to other processes or machines: its bytes and their hash.

    Workers of a dask cluster need not share a file system with the caller; and an
    evaluation is pinned to the FMU's content, the same content an archive keeps.
    """

    name: str
    sha256: str
    content: bytes = field(repr=False)

    @classmethod
    def from_path(cls, path: str | Path, name: str | None = None) -> "FmuRef":
        data = Path(path).read_bytes()
        return cls(name or Path(path).stem, hashlib.sha256(data).hexdigest(), data)


class LoadedFmu:
    """An FMU extracted once, its model description read and checked."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.is_file():
            raise FmuError(f"{self.path}: no such FMU file")
        if not zipfile.is_zipfile(self.path):
            raise FmuError(f"{self.path}: not an FMU (an FMU is a zip archive)")
        try:
            md = read_model_description(str(self.path), validate=False)
        except Exception as e:  # fmpy raises bare exceptions for missing or broken XML
            raise FmuError(f"{self.path}: cannot read modelDescription.xml ({e})") from None
        if md.fmiVersion != "2.0":
            raise FmuError(f"{self.path}: FMI {md.fmiVersion}; rapid-cosim simulates FMI 2.0 Model Exchange FMUs")
        if md.modelExchange is None:
            kinds = "Co-Simulation" if md.coSimulation is not None else "no"
            raise FmuError(f"{self.path}: a {kinds} FMU without a Model Exchange interface; "
                           "export it with Model Exchange (FMI 2.0 ME) to calibrate it here")
        self.model_description = md
        self.identifier = md.modelExchange.modelIdentifier
        with zipfile.ZipFile(self.path) as zf:
            names = set(zf.namelist())
        binary = f"binaries/{fmpy.platform}/{self.identifier}{fmpy.sharedLibraryExtension}"
        if binary not in names:
            have = sorted({n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2})
            raise FmuError(f"{self.path}: no binary for this platform ({binary}); the FMU has binaries for "
                           f"{', '.join(have) or 'no platform (a source-only FMU)'}")
        self.dir = Path(extract(str(self.path), unzipdir=tempfile.mkdtemp(prefix="rapid_cosim_fmu_")))
        self._finalizer = weakref.finalize(self, shutil.rmtree, str(self.dir), True)
        self.binary = self.dir / binary
        variables = md.modelVariables
        self.value_references = {v.name: v.valueReference for v in variables}
        self.types = {v.name: v.type for v in variables}
        self.parameters: dict[str, ParameterInfo] = {
            v.name: ParameterInfo(name=v.name, start=_float(v.start), min=_float(v.min), max=_float(v.max),
                                  unit=v.unit or "", description=v.description or "",
                                  settable=v.causality == "parameter" and v.type == "Real", type=v.type)
            for v in variables if v.causality in ("parameter", "calculatedParameter")}
        self.outputs = [v.name for v in variables if v.causality == "output"]
        self.inputs = [v.name for v in variables if v.causality == "input"]
        self.variables = [v.name for v in variables]
        self.n_states = md.numberOfContinuousStates
        self.n_event_indicators = md.numberOfEventIndicators

    @property
    def name(self) -> str:
        return self.model_description.modelName

    @property
    def resource_uri(self) -> str:
        return (self.dir / "resources").as_uri()

    def close(self) -> None:
        self._finalizer()

    # ---- checks a run needs

    def check_parameters(self, values: Mapping[str, float]) -> dict[str, float]:
        """Names known and settable, values finite and inside the declared min/max."""
        checked = {}
        for name, value in values.items():
            info = self.parameters.get(name)
            if info is None:
                close = difflib.get_close_matches(name, self.parameters, n=3)
                hint = f"; did you mean {', '.join(close)}?" if close else ""
                raise ParameterError(f"{self.name} has no parameter {name!r}{hint}")
            if info.type != "Real":
                raise ParameterError(f"{name} of {self.name} is a {info.type} parameter; only Real "
                                     "parameters can be set or estimated")
            if not info.settable:
                raise ParameterError(f"{name} of {self.name} is calculated from other parameters and cannot be set")
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"{name} = {value!r} is not a number") from None
            if not math.isfinite(value):
                raise ParameterError(f"{name} = {value} is not finite")
            if (info.min is not None and value < info.min) or (info.max is not None and value > info.max):
                raise ParameterError(
                    f"{name} = {value:g} is outside its declared range [{_fmt(info.min)}, {_fmt(info.max)}]"
                    f" in {self.name}")
            checked[name] = value
        return checked

    def output_types(self, names: Sequence[str]) -> list[int]:
        """The runner's type code per recorded variable; unknown or String ones refused."""
        unknown = [n for n in names if n not in self.types]
        if unknown:
            close = {n: difflib.get_close_matches(n, self.variables, n=3) for n in unknown}
            hints = "; ".join(f"{n}" + (f" (did you mean {', '.join(c)}?)" if c else "") for n, c in close.items())
            raise ParameterError(f"{self.name} has no variable(s) {hints}")
        bad = [f"{n} ({self.types[n]})" for n in names if self.types[n] not in OUTPUT_TYPES]
        if bad:
            raise ParameterError(f"{self.name}: cannot record {', '.join(bad)}; Real, Integer, Enumeration and "
                                 "Boolean variables can be recorded")
        return [OUTPUT_TYPES[self.types[n]] for n in names]

    def check_inputs(self, names: Sequence[str]) -> None:
        """The inputs given are exactly the FMU's inputs, all of type Real."""
        missing = [n for n in self.inputs if n not in names]
        extra = [n for n in names if n not in self.inputs]
        if missing or extra:
            raise ParameterError(f"{self.name} has inputs {self.inputs or '(none)'}; "
                                 f"missing {missing}, unknown {extra}")
        bad = [f"{n} ({self.types[n]})" for n in names if self.types[n] != "Real"]
        if bad:
            raise ParameterError(f"{self.name}: input(s) {', '.join(bad)} are not Real; rapid-cosim drives "
                                 "Real inputs only")


def _float(value) -> float | None:
    try:
        return None if value is None else float(value)
    except (TypeError, ValueError):
        return None


def _fmt(value: float | None) -> str:
    return "-inf" if value is None else f"{value:g}"


# The package's only global state: per process, the FMUs it has loaded.
_REF_FILES: dict[str, Path] = {}


def materialise(ref: FmuRef) -> Path:
    """A file holding ``ref``'s bytes, written once per process."""
    path = _REF_FILES.get(ref.sha256)
    if path is None or not path.exists():
        folder = Path(tempfile.gettempdir()) / f"rapid_cosim_fmus_{os.getpid()}"
        folder.mkdir(exist_ok=True)
        path = folder / f"{ref.sha256[:16]}.fmu"
        path.write_bytes(ref.content)
        _REF_FILES[ref.sha256] = path
    return path


def cache_key(fmu: str | Path | FmuRef) -> tuple[tuple, Path]:
    """A key that changes when the FMU's content may have (hash, or path with mtime and
    size), and the file to load it from."""
    if isinstance(fmu, FmuRef):
        return ("sha256", fmu.sha256), materialise(fmu)
    name = os.path.abspath(fmu)  # not resolve(): it costs a tenth of a staged run per call
    try:
        stat = os.stat(name)
    except OSError:
        stat = None
    if stat is None or not S_ISREG(stat.st_mode):
        raise FmuError(f"{name}: no such FMU file")
    return (name, stat.st_mtime_ns, stat.st_size), Path(name)
