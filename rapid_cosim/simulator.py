"""FMU -> trajectories, on fmpy, with one instance per FMU and process.

fmpy re-extracts an FMU given as a ``.fmu`` path on every call, even with
``fmu_instance``; instantiating costs a library load. A :class:`Simulator` extracts and
instantiates once and ``reset()``s between runs. Instances cannot be pickled, so each
process (each joblib worker) keeps its own, through :func:`get_simulator`: the one piece
of global state in the package.
"""

from __future__ import annotations

import difflib
import hashlib
import math
import os
import shutil
import tempfile
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from fmpy import extract, instantiate_fmu, read_model_description, simulate_fmu

from .errors import ParameterError, SimulationError, SimulationTimeout


@dataclass(frozen=True)
class ParameterInfo:
    name: str
    start: float | None
    min: float | None
    max: float | None
    unit: str
    description: str
    settable: bool  # False for calculated parameters


@dataclass(frozen=True)
class Trajectory:
    time: np.ndarray
    outputs: dict[str, np.ndarray]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.outputs[name]


class Simulator:
    """A model exchange FMU ready to run many times with different parameters."""

    def __init__(self, fmu: str | Path, *, timeout: float | None = None, relative_tolerance: float = 1e-6):
        self.path = Path(fmu)
        self.timeout = timeout
        self.relative_tolerance = relative_tolerance
        self.model_description = read_model_description(str(self.path), validate=False)
        self._dir = extract(str(self.path), unzipdir=tempfile.mkdtemp(prefix="rapid_cosim_fmu_"))
        self._finalizer = weakref.finalize(self, shutil.rmtree, self._dir, True)
        self._instance = instantiate_fmu(self._dir, self.model_description, fmi_type="ModelExchange")
        self._fresh = True
        variables = self.model_description.modelVariables
        self.parameters: dict[str, ParameterInfo] = {
            v.name: ParameterInfo(
                name=v.name,
                start=_float(v.start),
                min=_float(v.min),
                max=_float(v.max),
                unit=v.unit or "",
                description=v.description or "",
                settable=v.causality == "parameter",
            )
            for v in variables
            if v.causality in ("parameter", "calculatedParameter")
        }
        self.outputs: list[str] = [v.name for v in variables if v.causality == "output"]
        self.inputs: list[str] = [v.name for v in variables if v.causality == "input"]
        self.variables: list[str] = [v.name for v in variables]

    @property
    def name(self) -> str:
        return self.model_description.modelName

    def check_parameters(self, values: Mapping[str, float]) -> dict[str, float]:
        """Names known and settable, values finite and inside the declared min/max."""
        checked = {}
        for name, value in values.items():
            info = self.parameters.get(name)
            if info is None:
                close = difflib.get_close_matches(name, self.parameters, n=3)
                hint = f"; did you mean {', '.join(close)}?" if close else ""
                raise ParameterError(f"{self.name} has no parameter {name!r}{hint}")
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

    def simulate(self, parameters: Mapping[str, float] | None = None, *, stop_time: float,
                 output_interval: float, outputs: Sequence[str] | None = None, start_time: float = 0.0,
                 input_time: np.ndarray | None = None, inputs: Mapping[str, np.ndarray] | None = None,
                 check: bool = True) -> Trajectory:
        """Run once from ``start_time``; outputs on the grid start + k * output_interval.

        The run goes on to the first grid point at or after ``stop_time`` (fmpy records
        only on the grid), so the trajectory always covers ``stop_time``. ``inputs`` are
        sampled at ``input_time`` and interpolated linearly; to make a step, repeat its
        time with the values before and after (fmpy's convention).
        """
        if not output_interval > 0:
            raise ParameterError(f"output_interval must be positive, got {output_interval}")
        n_points = math.ceil((stop_time - start_time) / output_interval - 1e-9)
        stop_time = start_time + max(n_points, 1) * output_interval
        params = self.check_parameters(parameters or {}) if check else dict(parameters or {})
        names = list(outputs) if outputs is not None else self.outputs
        unknown = [n for n in names if n not in self.variables]
        if unknown:
            raise ParameterError(f"{self.name} has no variable(s) {', '.join(unknown)}")
        signals = self._input_table(input_time, inputs)
        if not self._fresh:
            self._instance.reset()
        self._fresh = False
        try:
            result = simulate_fmu(
                self._dir, validate=False, start_time=start_time, stop_time=stop_time, solver="CVode",
                relative_tolerance=self.relative_tolerance, output_interval=output_interval,
                record_events=False, start_values=params, input=signals, output=names,
                timeout=self.timeout, model_description=self.model_description, fmu_instance=self._instance,
            )
        except Exception as e:  # fmpy raises bare Exceptions for FMI errors and CVode failures
            self._recover()
            raise SimulationError(f"{self.name} failed with {_describe(params)}: {e}") from e
        time = np.asarray(result["time"], dtype=float)
        if time.size == 0 or time[-1] < stop_time - 1e-9 * max(1.0, abs(stop_time)):
            self._recover()
            reached = time[-1] if time.size else start_time
            raise SimulationTimeout(
                f"{self.name} stopped at t={reached:g} of {stop_time:g} s after the {self.timeout} s time-out "
                f"with {_describe(params)}")
        return Trajectory(time, {n: np.asarray(result[n], dtype=float) for n in names})

    def _input_table(self, input_time, inputs):
        if not inputs:
            if self.inputs:
                # fmpy would silently hold the start values; say so instead.
                raise ParameterError(f"{self.name} has inputs {', '.join(self.inputs)}; give them values")
            return None
        missing = [n for n in self.inputs if n not in inputs]
        extra = [n for n in inputs if n not in self.inputs]
        if missing or extra:
            raise ParameterError(f"{self.name} inputs are {self.inputs}; missing {missing}, unknown {extra}")
        t = np.asarray(input_time, dtype=float)
        table = np.zeros(t.size, dtype=[("time", float)] + [(n, float) for n in self.inputs])
        table["time"] = t
        for n in self.inputs:
            table[n] = np.asarray(inputs[n], dtype=float)
        return table

    def _recover(self) -> None:
        """After a failure the instance may be in any state; a reset brings it back."""
        try:
            self._instance.reset()
        except Exception:
            self._instance.freeInstance()
            self._instance = instantiate_fmu(self._dir, self.model_description, fmi_type="ModelExchange")
        self._fresh = True

    def close(self) -> None:
        try:
            self._instance.freeInstance()
        finally:
            self._finalizer()


def _float(value) -> float | None:
    try:
        return None if value is None else float(value)
    except (TypeError, ValueError):
        return None


def _fmt(value: float | None) -> str:
    return "-inf" if value is None else f"{value:g}"


def _describe(params: Mapping[str, float]) -> str:
    return ", ".join(f"{k}={v:.6g}" for k, v in params.items()) or "default parameters"


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


# The package's only global state: per process, the simulators of the FMUs it has loaded.
_CACHE: dict[tuple, Simulator] = {}
_REF_FILES: dict[str, Path] = {}


def _materialise(ref: FmuRef) -> Path:
    path = _REF_FILES.get(ref.sha256)
    if path is None or not path.exists():
        folder = Path(tempfile.gettempdir()) / f"rapid_cosim_fmus_{os.getpid()}"
        folder.mkdir(exist_ok=True)
        path = folder / f"{ref.sha256[:16]}.fmu"
        path.write_bytes(ref.content)
        _REF_FILES[ref.sha256] = path
    return path


def get_simulator(fmu: str | Path | FmuRef, *, timeout: float | None = None) -> Simulator:
    """The process's simulator for ``fmu``: loaded once, again only if the file changed."""
    if isinstance(fmu, FmuRef):
        key: tuple = ("sha256", fmu.sha256)
        path = None
    else:
        path = Path(fmu).resolve()
        stat = path.stat()
        key = (str(path), stat.st_mtime_ns, stat.st_size)
    sim = _CACHE.get(key)
    if sim is None:
        for old in [k for k in _CACHE if k[0] == key[0] and k[0] != "sha256"]:
            _CACHE.pop(old).close()
        sim = _CACHE[key] = Simulator(path if path is not None else _materialise(fmu), timeout=timeout)
    sim.timeout = timeout
    return sim
