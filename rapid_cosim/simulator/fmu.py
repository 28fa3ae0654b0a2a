"""An FMU file -> a checked, extracted model: what the simulator needs to know of it.

Any FMI 2.0 or 3.0 FMU with a Model Exchange or a Co-Simulation interface is accepted,
whoever built it. Model Exchange is used where the FMU has it (rapid-cosim's own
integrators, :mod:`.compiled`); a Co-Simulation-only FMU runs with its own solver
(:mod:`.cosim`). It is checked once, on load, with one clear error per problem: the FMI
version, an interface, a binary for this platform, clocks, and variables a run cannot
drive (non-Real inputs or parameters given values, String or Binary outputs) are refused
by name when they are asked for. Inputs not given are held at their start values. FMI 3.0
arrays of a size the model description gives are recorded element by element. Outputs
that are not numbers are left out when none are named (:attr:`LoadedFmu.skipped_outputs`).

:class:`FmuRef` carries an FMU by content, so that it can travel to other processes or
machines and be archived; :func:`load_fmu` keeps one extracted copy per FMU and process
(the package's only global state).
"""

from __future__ import annotations

import difflib
import hashlib
import itertools
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

# How the runners read an output of each FMI type (the codes of fmi3_table.h; FMI 2.0 has
# the first three, Enumeration read as an Integer, in FMI 3.0 as an Int64).
OUTPUT_TYPES = {"Real": 0, "Float64": 0, "Integer": 1, "Int32": 1, "Boolean": 2, "Float32": 3, "Int8": 4,
                "UInt8": 5, "Int16": 6, "UInt16": 7, "UInt32": 8, "Int64": 9, "UInt64": 10}
ENUMERATION = {"2.0": 1, "3.0": 9}
# One element of an FMI 3.0 array, recorded as a variable of its own ("y[2]", "A[1,2]"): a
# flag on its type's code, its offset and its array's size passed beside (fmi3_table.h).
ELEMENT, MAX_ELEMENTS = 16, 1024
REAL_TYPES = ("Real", "Float64")  # what inputs may be (FMI 2.0, FMI 3.0), and estimated parameters
# Parameters that can be set, with the runners' type codes: FMI 2.0's Integer and Boolean
# flags too (GGOV1's Rselect), each set by its own function; FMI 3.0 sets Float64 only.
PARAMETER_TYPES = {"Real": 0, "Float64": 0, "Integer": 1, "Boolean": 2}
FLAG_TYPES = ("Integer", "Boolean")
MODEL_EXCHANGE, CO_SIMULATION = "ModelExchange", "CoSimulation"
INTERFACE_NAMES = {MODEL_EXCHANGE: "Model Exchange", CO_SIMULATION: "Co-Simulation"}


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


EXTRACTED = "rapid_cosim_fmu_p"  # an extracted FMU's folder: rapid_cosim_fmu_p<pid>_<random>


def _extraction_dir() -> str:
    """A fresh temporary folder for an FMU's files, named by this process; the folders of
    processes that are gone are removed first (a worker killed mid-run never runs its
    finalizer, and a fleet's killed workers left hundreds)."""
    root = Path(tempfile.gettempdir())
    for old in root.glob(EXTRACTED + "*"):
        pid = old.name[len(EXTRACTED):].split("_", 1)[0]
        if pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(old, ignore_errors=True)
    return tempfile.mkdtemp(prefix=f"{EXTRACTED}{os.getpid()}_")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def _checked_description(path: Path, interface: str | None):
    """(model description, FMI version, the interface it runs through) of an FMU that
    rapid-cosim can simulate; else an FmuError naming the file and what it lacks."""
    if not path.is_file():
        raise FmuError(f"{path}: no such FMU file")
    if not zipfile.is_zipfile(path):
        raise FmuError(f"{path}: not an FMU (an FMU is a zip archive)")
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as e:  # fmpy raises bare exceptions for missing or broken XML
        raise FmuError(f"{path}: cannot read modelDescription.xml ({e})") from None
    version = "3.0" if str(md.fmiVersion).startswith("3.") else md.fmiVersion
    if version not in ("2.0", "3.0"):
        raise FmuError(f"{path}: FMI {md.fmiVersion}; rapid-cosim simulates FMI 2.0 and 3.0 FMUs")
    offered = [name for name, part in ((MODEL_EXCHANGE, md.modelExchange), (CO_SIMULATION, md.coSimulation))
               if part is not None]
    clocks = [v.name for v in md.modelVariables if v.type == "Clock"]
    if not offered:
        what = ("only a Scheduled Execution interface (model partitions activated by FMI 3.0 clocks"
                f"{' ' + ', '.join(clocks) if clocks else ''})"
                if getattr(md, "scheduledExecution", None) is not None else
                "neither a Model Exchange nor a Co-Simulation interface")
        raise FmuError(f"{path}: an FMU with {what}; rapid-cosim simulates Model Exchange and "
                       "Co-Simulation FMUs")
    if clocks:
        raise FmuError(f"{path}: FMI 3.0 clocks ({', '.join(clocks)}) need event handling by clock, "
                       "which rapid-cosim does not do; it simulates FMUs without clocks")
    if interface is not None and interface not in offered:
        raise FmuError(f"{path}: no {INTERFACE_NAMES.get(interface, interface)} interface; the FMU offers "
                       f"{', '.join(INTERFACE_NAMES[o] for o in offered)}")
    return md, version, interface or offered[0]


class LoadedFmu:
    """An FMU extracted once, its model description read and checked.

    ``interface`` is the one it runs through: Model Exchange where the FMU has it, else
    Co-Simulation (``interface=`` chooses, for an FMU that has both)."""

    def __init__(self, path: str | Path, interface: str | None = None):
        self.path = Path(path)
        md, version, self.interface = _checked_description(self.path, interface)
        self.model_description = md
        self.fmi_version = version
        part = md.modelExchange if self.interface == MODEL_EXCHANGE else md.coSimulation
        self.identifier = part.modelIdentifier
        with zipfile.ZipFile(self.path) as zf:
            names = set(zf.namelist())
        folder = fmpy.platform_tuple if self.fmi3 else fmpy.platform
        binary = f"binaries/{folder}/{self.identifier}{fmpy.sharedLibraryExtension}"
        if binary not in names:
            have = sorted({n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2})
            raise FmuError(f"{self.path}: no binary for this platform ({binary}); the FMU has binaries for "
                           f"{', '.join(have) or 'no platform (a source-only FMU)'}")
        self.dir = Path(extract(str(self.path), unzipdir=_extraction_dir()))
        self._finalizer = weakref.finalize(self, shutil.rmtree, str(self.dir), True)
        self.binary = self.dir / binary
        variables = md.modelVariables
        self.value_references = {v.name: v.valueReference for v in variables}
        # arrays (FMI 3.0 dimensions) are not simulated: their type says so
        self.types = {v.name: v.type if not getattr(v, "dimensions", None) else f"{v.type}[]" for v in variables}
        self.elements: dict[str, tuple[int, int]] = {}  # array element -> (offset, size of the array)
        self.arrays: dict[str, list[str]] = {}  # FMI 3.0 array of a known size -> its elements, row-major
        by_vr = {v.valueReference: v for v in variables}
        for v in variables:
            shape = _shape(v, by_vr) if getattr(v, "dimensions", None) else None
            if shape is None or not 0 < math.prod(shape) <= MAX_ELEMENTS:
                continue
            names = [f"{v.name}[{','.join(map(str, index))}]" for index in
                     itertools.product(*(range(1, d + 1) for d in shape))]
            self.arrays[v.name] = names
            for offset, name in enumerate(names):
                self.elements[name] = (offset, len(names))
                self.types[name] = v.type
                self.value_references[name] = v.valueReference
        self.parameters: dict[str, ParameterInfo] = {
            v.name: ParameterInfo(name=v.name, start=_float(v.start), min=_float(v.min), max=_float(v.max),
                                  unit=v.unit or "", description=v.description or "",
                                  settable=v.causality == "parameter" and (
                                      self.types[v.name] in REAL_TYPES
                                      or (self.types[v.name] in FLAG_TYPES and not self.fmi3)),
                                  type=self.types[v.name])
            for v in variables if v.causality in ("parameter", "calculatedParameter")}
        self.outputs = [v.name for v in variables if v.causality == "output"]
        self.inputs = [v.name for v in variables if v.causality == "input"]
        self.input_starts = {v.name: v.start for v in variables if v.causality == "input"}  # as declared (text)
        self.variables = [v.name for v in variables]
        self.n_states = md.numberOfContinuousStates
        self.n_event_indicators = md.numberOfEventIndicators
        intermediate = _intermediate_update(self.path) if self.fmi3 else set()
        cs = md.coSimulation
        # Co-Simulation: how inputs reach the FMU's solver between communication points
        if cs is None or not self.inputs:
            self.input_interpolation = "hold"
        elif not self.fmi3:
            self.input_interpolation = "derivatives" if cs.canInterpolateInputs else "hold"
        else:
            self.input_interpolation = "intermediate" if cs.providesIntermediateUpdate and \
                set(self.inputs) <= intermediate else "hold"
        self.variable_step = bool(cs is not None and cs.canHandleVariableCommunicationStepSize)

    @property
    def name(self) -> str:
        return self.model_description.modelName

    @property
    def fmi3(self) -> bool:
        return self.fmi_version == "3.0"

    @property
    def co_simulation(self) -> bool:
        """Runs through its Co-Simulation interface (the FMU's own solver)."""
        return self.interface == CO_SIMULATION

    @property
    def kind(self) -> str:
        """E.g. "FMI 3.0 Co-Simulation"."""
        return f"FMI {self.fmi_version} {INTERFACE_NAMES[self.interface]}"

    @property
    def resource_uri(self) -> str:
        return (self.dir / "resources").as_uri()

    @property
    def resource_location(self) -> str:
        """What instantiation is given: FMI 2.0 a URI, FMI 3.0 a path ending in a separator."""
        return str(self.dir / "resources") + os.sep if self.fmi3 else self.resource_uri

    def _numeric(self, name: str) -> bool:
        return self.types[name] in OUTPUT_TYPES or self.types[name] == "Enumeration"

    @property
    def numeric_outputs(self) -> list[str]:
        """The outputs a run records when none are named: those that are numbers, an
        array's elements in its place."""
        return [e for n in self.outputs for e in self.expand_outputs([n]) if self._numeric(e)]

    @property
    def skipped_outputs(self) -> list[str]:
        """Outputs left out when none are named (String, Binary, Clock, arrays of those or
        of a size not known from the model description)."""
        return [n for n in self.outputs if not any(self._numeric(e) for e in self.expand_outputs([n]))]

    def expand_outputs(self, names: Sequence[str]) -> list[str]:
        """The names, an FMI 3.0 array's in place of its elements ("y" -> "y[1]", "y[2]")."""
        return [e for n in names for e in self.arrays.get(n, [n])]

    def output_elements(self, names: Sequence[str]):
        """(offset, size) per name, an int32 array for the runners; None when no name is
        an array element."""
        if not any(n in self.elements for n in names):
            return None
        import numpy as np

        return np.array([self.elements.get(n, (0, 1)) for n in names], dtype=np.int32)

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
            if info.type not in REAL_TYPES and (self.fmi3 or info.type not in FLAG_TYPES):
                raise ParameterError(f"{name} of {self.name} is a {info.type} parameter; Real parameters (FMI 2.0 "
                                     "Integer and Boolean ones too; FMI 3.0: Float64) can be set")
            if not info.settable:
                raise ParameterError(f"{name} of {self.name} is calculated from other parameters and cannot be set")
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"{name} = {value!r} is not a number") from None
            if not math.isfinite(value):
                raise ParameterError(f"{name} = {value} is not finite")
            if info.type == "Integer" and value != round(value):
                raise ParameterError(f"{name} = {value:g} is not a whole number: it is an Integer parameter of "
                                     f"{self.name}")
            if info.type == "Boolean" and value not in (0.0, 1.0):
                raise ParameterError(f"{name} = {value:g}: it is a Boolean parameter of {self.name}; give 0 or 1")
            if (info.min is not None and value < info.min) or (info.max is not None and value > info.max):
                raise ParameterError(
                    f"{name} = {value:g} is outside its declared range [{_fmt(info.min)}, {_fmt(info.max)}]"
                    f" in {self.name}")
            checked[name] = value
        return checked

    def parameter_types(self, names: Sequence[str]):
        """The runners' type code per parameter set (0 Real, 1 Integer, 2 Boolean), an
        int32 array, or None when all are Real (the runners then set them in one call)."""
        import numpy as np

        codes = np.array([PARAMETER_TYPES.get(self.types[n], 0) for n in names], dtype=np.int32)
        return codes if codes.any() else None

    def output_types(self, names: Sequence[str]) -> list[int]:
        """The runner's type code per recorded variable; unknown or String ones refused."""
        unknown = [n for n in names if n not in self.types]
        if unknown:
            close = {n: difflib.get_close_matches(n, self.variables, n=3) for n in unknown}
            hints = "; ".join(f"{n}" + (f" (did you mean {', '.join(c)}?)" if c else "") for n, c in close.items())
            raise ParameterError(f"{self.name} has no variable(s) {hints}")
        def code(n):
            kind = self.types[n]
            c = ENUMERATION[self.fmi_version] if kind == "Enumeration" else OUTPUT_TYPES.get(kind)
            return c if c is None or n not in self.elements else c | ELEMENT

        bad = [f"{n} ({self.types[n]})" for n in names if code(n) is None]
        if bad:
            raise ParameterError(f"{self.name}: cannot record {', '.join(bad)}; numeric variables (Real, Integer, "
                                 "Enumeration and Boolean; in FMI 3.0 the Float and Int types, and the elements "
                                 "of arrays whose size the model description gives) can be recorded")
        return [code(n) for n in names]

    def check_inputs(self, names: Sequence[str]) -> dict[str, str]:
        """The inputs given are the FMU's, of type Real; returns those not given, which
        are held at their declared start values (name -> start, as declared), as fmpy
        holds them. One without a start value has no value to hold: refused."""
        extra = [n for n in names if n not in self.inputs]
        if extra:
            raise ParameterError(f"{self.name} has inputs {self.inputs or '(none)'}; unknown {extra}")
        bad = [f"{n} ({self.types[n]})" for n in names if self.types[n] not in REAL_TYPES]
        if bad:
            raise ParameterError(f"{self.name}: input(s) {', '.join(bad)} are not Real; rapid-cosim drives "
                                 "Real (FMI 3.0: Float64) inputs only")
        held = {n: self.input_starts[n] for n in self.inputs if n not in names}
        unset = [n for n, start in held.items() if start is None]
        if unset:
            raise ParameterError(f"{self.name} has inputs {', '.join(self.inputs)}; {', '.join(unset)} "
                                 f"{'has' if len(unset) == 1 else 'have'} no start value to hold: give "
                                 f"{'it' if len(unset) == 1 else 'them'} values")
        return held

    def describe_held(self, held: Mapping[str, str]) -> str:
        """E.g. "u = 0, flag = false, label = 'Set me!'" (String and Binary starts quoted)."""
        quoted = ("String", "Binary")
        return ", ".join(f"{n} = {start!r}" if self.types[n] in quoted else
                         f"{n} = [{start}]" if self.types[n].endswith("[]") else f"{n} = {start}"
                         for n, start in held.items())


def _intermediate_update(path: Path) -> set[str]:
    """FMI 3.0 variables with ``intermediateUpdate="true"`` (fmpy 0.3.32 does not read the
    attribute)."""
    import xml.etree.ElementTree as ET

    with zipfile.ZipFile(path) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    variables = root.find("ModelVariables")
    return {v.get("name") for v in (variables if variables is not None else [])
            if v.get("intermediateUpdate") in ("true", "1")}


def _shape(v, by_vr) -> tuple[int, ...] | None:
    """An FMI 3.0 array's dimensions: given, or the start values of the structural
    parameters that size them (not settable here, so fixed); None if one is not known."""
    shape = []
    for d in v.dimensions:
        size = d.start if d.start is not None else getattr(by_vr.get(d.valueReference), "start", None)
        try:
            shape.append(int(size))
        except (TypeError, ValueError):
            return None
    return tuple(shape)


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


def set_parameters(instance, fmi3: bool, vrs: Sequence[int], values: Sequence[float], kinds) -> None:
    """Parameters on an fmpy instance, each by its type (``kinds`` as
    :meth:`Fmu.parameter_types`; None: all Real), as the C runners set them."""
    if not vrs:
        return
    if fmi3:
        instance.setFloat64(list(vrs), list(values))
    elif kinds is None:
        instance.setReal(list(vrs), list(values))
    else:
        for vr, value, kind in zip(vrs, values, kinds):
            if kind == 1:
                instance.setInteger([vr], [int(round(value))])
            elif kind == 2:
                instance.setBoolean([vr], [bool(value)])
            else:
                instance.setReal([vr], [float(value)])
