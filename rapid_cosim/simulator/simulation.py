"""FMU -> trajectories: one simulator per FMU and process, single runs and batches.

Three runners do the work: ``"exponential"`` (the default: the C library's exponential
integrator, ``expint.c``: one model evaluation per sample, exact for the model's linear
part, CVODE wherever its error estimate or the FMU asks for it), ``"compiled"`` (the same
library's CVODE path, ``runner.c``: what archives made before the exponential runner
record) and ``"python"`` (:mod:`.reference`, the Python loop both are checked against, and
what archives made before the compiled runner record). All record outputs at given times
(the measured samples, so no interpolation stands between model and data) or on a grid,
with values at a time event being those after it. Archives record the runner that made
them, and each runner repeats its own numbers bit for bit.

Why "exponential" is the default (2 cores): it is closer to a tight reference than CVODE
at CVODE's default tolerance everywhere tried, by far where limits act: CVODE at rtol 1e-6
is 1.9e-3 pu off on a backlash bench and 1.3e-3 on TGOV1 held at VMAX with a noisy
recorded input, the exponential runner within 2e-6 (1e-9 to 1e-8 on linear benches). It
is 2.3 to 3.6 times faster on a 120 s PMU record at 50 frames/s, and 1.0 to 1.7 times on
the diagnosis catalogue's staged benches. It is slower (up to 1.7 times) on staged tests of
the stiff, strongly limited structures (GGOV1 with its gate, HYGOV's velocity limit),
where its error control keeps handing steps to CVODE.

A failed set is never an exception inside a batch: it gets a status and a message (and
NaN outputs), and the rest of the batch runs. :meth:`Simulator.simulate` runs one set
and raises :class:`SimulationError` or :class:`SimulationTimeout` instead.

FMI 3.0 Model Exchange FMUs run through the same C runners (an adapter gives the FMI 3.0
functions FMI 2.0's shape: ``runner.c``) and the same Python loop. Co-Simulation-only FMUs, FMI 2.0 or 3.0, run
with their own solver through :mod:`.cosim`: the C driver for runners "compiled" and
"exponential", fmpy's slave classes for "python". :meth:`Simulator.path` names the path a
runner takes; archives record it.

Inputs not given are held at their declared start values, as fmpy holds them (an
:class:`InputsHeld` note names them); one without a start value must be given.

A model may ask to terminate (FMI's terminateSimulation). Its set then keeps the outputs
up to that moment (NaN after) with the status "terminated", a failure in a batch and in a
calibration; :meth:`Simulator.simulate` returns the trajectory up to that time with a
:class:`ModelTerminated` warning. A set that stops at or after its last output time has
given everything asked and is ok.
"""

from __future__ import annotations

import hashlib
import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..errors import FmuError, ParameterError, SimulationError, SimulationTimeout
from . import compiled
from .fmu import FmuRef, LoadedFmu, ParameterInfo, cache_key
from .inputs import InputTable
from .rocof import FREQUENCY, ROCOF, with_rocof, without_rocof
from .delayed import DELAY, DELAYED_FREQUENCY, delayed_table, set_delays, with_delayed

RUNNERS = ("compiled", "python", "exponential")  # archives record these names
DEFAULT_RUNNER = "exponential"


class ModelTerminated(UserWarning):
    """The model asked to terminate the simulation before its last output time; the
    trajectory ends there."""


class OutputsSkipped(UserWarning):
    """Outputs that are not numbers (String, Binary, arrays) were left out of a run that
    named none."""


class InputsHeld(UserWarning):
    """Inputs not given are held at their declared start values (as fmpy holds them);
    the note names them and the values."""


@dataclass(frozen=True)
class Trajectory:
    """Outputs on one time base, by name. An FMI 3.0 array output is kept element by
    element (``y[1]``, ``y[2]``, as its scalar variables are recorded); asked for by its own
    name (``traj["y"]``) it is one array of shape (times, *dims), as fmpy returns it."""

    time: np.ndarray
    outputs: dict[str, np.ndarray]

    def __getitem__(self, name: str) -> np.ndarray:
        if name in self.outputs:
            return self.outputs[name]
        elements = {}
        for key in self.outputs:
            m = re.fullmatch(re.escape(name) + r"\[([\d,\s]+)\]", key)
            if m:
                elements[tuple(int(i) for i in m.group(1).split(","))] = self.outputs[key]
        if not elements:
            raise KeyError(f"{name!r}: no such output; recorded: {', '.join(self.outputs)}")
        dims = tuple(max(ix[k] for ix in elements) for k in range(len(next(iter(elements)))))
        out = np.full((self.time.size, *dims), np.nan)
        for ix, values in elements.items():
            out[(slice(None), *(i - 1 for i in ix))] = values
        return out


@dataclass(frozen=True, eq=False)
class BatchResult:
    """Outputs of many parameter sets on one time base: ``values`` is (sets, times, outputs)."""

    time: np.ndarray
    outputs: tuple[str, ...]
    values: np.ndarray
    status: np.ndarray  # runner status per set, 0 = ok (see compiled.STATUS_NAMES)
    messages: tuple[str, ...]

    @property
    def ok(self) -> np.ndarray:
        return self.status == compiled.OK

    def trajectory(self, i: int = 0) -> Trajectory:
        return Trajectory(self.time, {n: self.values[i, :, j] for j, n in enumerate(self.outputs)})


def check_runner(runner: str) -> str:
    if runner not in RUNNERS:
        raise ParameterError(f"unknown runner {runner!r}; choose one of {', '.join(RUNNERS)}")
    return runner


def time_base(start_time: float, stop_time: float | None, output_interval: float | None,
                 times: np.ndarray | None) -> np.ndarray:
    """The given increasing ``times``, or the grid start + k * interval continued to the
    first point at or after ``stop_time``."""
    if times is not None:
        t = np.asarray(times, dtype=float)
        if t.ndim != 1 or t.size == 0 or np.any(np.diff(t) <= 0) or t[0] < start_time:
            raise ParameterError("output_times must be increasing and start at or after start_time")
        return t
    if stop_time is None or output_interval is None or not output_interval > 0:
        raise ParameterError("give stop_time and a positive output_interval, or output_times")
    if not stop_time > start_time:
        raise ParameterError(f"stop_time {stop_time:g} s must be after start_time {start_time:g} s")
    n_points = max(math.ceil((stop_time - start_time) / output_interval - 1e-9), 1)
    return start_time + output_interval * np.arange(n_points + 1)


class Simulator:
    """An FMU ready to run many times with different parameters: FMI 2.0 or 3.0, through
    its Model Exchange interface where it has one (``interface="CoSimulation"`` chooses
    the other for an FMU with both), else its Co-Simulation interface."""

    def __init__(self, fmu: str | Path, *, timeout: float | None = None, relative_tolerance: float = 1e-6,
                 runner: str = DEFAULT_RUNNER, interface: str | None = None):
        self.fmu = LoadedFmu(fmu, interface)
        self.path = self.fmu.path
        self.timeout = timeout
        self.relative_tolerance = relative_tolerance
        self.runner = check_runner(runner)
        self._runners: dict[str, object] = {}
        self._batches: dict[tuple, PreparedBatch] = {}
        self._noted = False
        self._held_noted: set[tuple[str, ...]] = set()

    # the FMU's declarations
    name = property(lambda self: self.fmu.name)
    interface = property(lambda self: self.fmu.interface)
    kind = property(lambda self: self.fmu.kind)  # e.g. "FMI 3.0 Co-Simulation"
    model_description = property(lambda self: self.fmu.model_description)
    parameters: dict[str, ParameterInfo] = property(lambda self: self.fmu.parameters)  # type: ignore[assignment]
    outputs = property(lambda self: self.fmu.outputs)
    inputs = property(lambda self: self.fmu.inputs)
    variables = property(lambda self: self.fmu.variables)

    def check_parameters(self, values: Mapping[str, float]) -> dict[str, float]:
        return self.fmu.check_parameters(values)

    def run_path(self, runner: str | None = None) -> str:
        """What runs a simulation with ``runner``: the FMU's kind and the driver, e.g.
        "FMI 2.0 Model Exchange, exponential runner" or "FMI 3.0 Co-Simulation, C driver"."""
        name = check_runner(runner or self.runner)
        if self.fmu.co_simulation:
            return f"{self.fmu.kind}, {'fmpy loop' if name == 'python' else 'C driver'}"
        return f"{self.fmu.kind}, {name} runner"

    def _runner(self, runner: str | None):
        name = check_runner(runner or self.runner)
        key = ("cosim-python" if name == "python" else "cosim") if self.fmu.co_simulation else name
        if key not in self._runners:
            if self.fmu.co_simulation:
                from .cosim import CosimDriver, CosimLoop

                kind = CosimLoop if name == "python" else CosimDriver
                self._runners[key] = kind(self.fmu, self.relative_tolerance)
            elif name in ("compiled", "exponential"):
                method = "exponential" if name == "exponential" else "cvode"
                self._runners[key] = compiled.CompiledRunner(self.fmu, self.relative_tolerance, method)
            else:
                from .reference import ReferenceLoop

                self._runners[key] = ReferenceLoop(self.fmu, self.relative_tolerance)
        return name, self._runners[key]

    def _default_outputs(self) -> list[str]:
        """Every numeric output; the others noted once per simulator."""
        skipped = self.fmu.skipped_outputs
        if skipped and not self._noted:
            self._noted = True
            warnings.warn(f"{self.name}: output(s) {', '.join(f'{n} ({self.fmu.types[n]})' for n in skipped)} are "
                          "not numbers and are not recorded; name the outputs to record to silence this",
                          OutputsSkipped, stacklevel=4)
        return self.fmu.numeric_outputs

    def _input_table(self, input_time, inputs) -> tuple[InputTable | None, dict[str, str]]:
        """The table of the inputs given, and those held at their start values (noted once
        per simulator and set of inputs held)."""
        if isinstance(inputs, InputTable):
            table = inputs
        elif inputs:
            table = InputTable.from_columns(input_time, inputs)
        else:
            table = None
        if table is not None and ROCOF in self.inputs and FREQUENCY in table.names and ROCOF not in table.names:
            table = with_rocof(table)  # a recorded-frequency bench always gets its ROCOF (.rocof)
        elif table is not None and ROCOF in table.names and ROCOF not in self.inputs and FREQUENCY in table.names:
            table = without_rocof(table)  # an experiment's derived ROCOF, offered to a model without it
        if table is not None and DELAYED_FREQUENCY in self.inputs and FREQUENCY in table.names:
            table = with_delayed(table)  # a delayed bench's governor input: each set's made by the runner
        held = self.fmu.check_inputs(table.names if table is not None else ())
        if held and tuple(held) not in self._held_noted:
            self._held_noted.add(tuple(held))
            warnings.warn(f"{self.name}: input(s) not given are held at their start values: "
                          f"{self.fmu.describe_held(held)}", InputsHeld, stacklevel=5)
        return (table if table is not None and table.names else None), held

    def prepare(self, names: Sequence[str], *, output_times: np.ndarray | None = None,
                stop_time: float | None = None, output_interval: float | None = None,
                outputs: Sequence[str] | None = None, start_time: float = 0.0,
                input_time: np.ndarray | None = None, inputs: Mapping[str, np.ndarray] | InputTable | None = None,
                runner: str | None = None, communication_step: float | None = None) -> "PreparedBatch":
        """A batch whose parameters set, outputs, times and inputs are fixed, to be run
        with many value tables (see :meth:`simulate_batch`). ``communication_step`` (s)
        bounds a Co-Simulation FMU's communication step (see :mod:`.cosim`); Model
        Exchange FMUs ignore it."""
        record = self.fmu.expand_outputs(outputs) if outputs is not None else self._default_outputs()
        types = self.fmu.output_types(record)
        times = time_base(start_time, stop_time, output_interval, output_times)
        table, held = self._input_table(input_time, inputs)
        kind, run = self._runner(runner)
        names = list(names)

        def prepared(table):
            if self.fmu.co_simulation:
                return run.prepare(names, record, types, start_time, times, table, self.timeout, communication_step)
            if kind in ("compiled", "exponential"):
                return run.prepare(names, record, types, start_time, times, table, self.timeout)
            return lambda values: self._run_reference(run, names, values, record, types, start_time, times, table)

        if table is not None and DELAYED_FREQUENCY in table.names:
            if DELAY not in self.fmu.parameters:
                raise FmuError(f"{self.name}: an input {DELAYED_FREQUENCY} and no parameter {DELAY} to delay it by "
                               "(iGrGen.Effects.TransportDelay dly)")
            call = _set_by_set(prepared, table, names, self.fmu.parameters[DELAY].start)
        else:
            call = prepared(table)
        return PreparedBatch(self, names, tuple(record), times, call, held)

    def simulate_batch(self, names: Sequence[str], values, *, check: bool = True, **kwargs) -> BatchResult:
        """Run each row of ``values`` (sets x len(names)) from ``start_time``; the keywords
        are those of :meth:`prepare`.

        ``inputs`` (or an :class:`InputTable`) are sampled at ``input_time``, linear between
        rows; a repeated time is a step. ``check`` validates every value against the
        declared ranges (callers that checked their bounds once may skip it).
        """
        return self._prepared(names, kwargs).run(values, check=check)

    def _prepared(self, names: Sequence[str], kwargs: dict) -> "PreparedBatch":
        """:meth:`prepare`, remembered for a repeated call on the same grid and inputs (a
        notebook's parameter sweep through ``rc.simulate``), the latest few kept. Arrays
        enter the key by a digest of their bytes: planning a recorded event costs more than
        its run, hashing it (SHA-1) a tenth of that."""
        key = (tuple(names), self.timeout, *((k, _content(kwargs[k])) for k in sorted(kwargs)))
        batch = self._batches.pop(key, None) or self.prepare(names, **kwargs)
        self._batches[key] = batch  # most recent last
        while len(self._batches) > _PREPARED_KEPT:
            self._batches.pop(next(iter(self._batches)))
        return batch

    def _run_reference(self, loop, names, values, record, types, start_time, times, table):
        out = np.full((values.shape[0], times.size, len(record)), np.nan)
        status = np.zeros(values.shape[0], dtype=np.int32)
        messages = []
        from .reference import Terminated

        for i, row in enumerate(values):
            try:
                out[i] = loop.run(dict(zip(names, row.tolist())), record, types, start_time, times, table,
                                  self.timeout)
                if not np.all(np.isfinite(out[i])):
                    status[i], out[i] = compiled.NONFINITE, np.nan
                    messages.append("an output is not finite")
                    continue
                messages.append("")
            except Terminated as e:
                out[i] = e.out
                status[i] = compiled.TERMINATED
                messages.append(str(e))
            except SimulationTimeout as e:
                status[i] = compiled.TIMEOUT
                messages.append(str(e))
            except Exception as e:  # fmpy raises bare Exceptions for FMI errors and CVode failures
                status[i] = compiled.SOLVER
                messages.append(str(e))
        return out, status, messages

    def simulate(self, parameters: Mapping[str, float] | None = None, *, stop_time: float | None = None,
                 output_interval: float | None = None, output_times: np.ndarray | None = None,
                 outputs: Sequence[str] | None = None, start_time: float = 0.0,
                 input_time: np.ndarray | None = None, inputs: Mapping[str, np.ndarray] | InputTable | None = None,
                 check: bool = True, runner: str | None = None, communication_step: float | None = None) -> Trajectory:
        """One run; see :meth:`simulate_batch`. A failure raises :class:`SimulationError`
        (:class:`SimulationTimeout` for the wall-clock budget). A model that asks to
        terminate before the last output time gives the trajectory up to that time, with a
        :class:`ModelTerminated` warning."""
        params = self.check_parameters(parameters or {}) if check else dict(parameters or {})
        result = self.simulate_batch(list(params), np.array([list(params.values())]), output_times=output_times,
                                     stop_time=stop_time, output_interval=output_interval, outputs=outputs,
                                     start_time=start_time, input_time=input_time, inputs=inputs, runner=runner,
                                     check=False, communication_step=communication_step)
        status = int(result.status[0])
        if status == compiled.TIMEOUT:
            raise SimulationTimeout(f"{result.messages[0]} (time-out {self.timeout} s)")
        if status == compiled.TERMINATED:
            return self._until_terminated(result)
        if status != compiled.OK:
            raise SimulationError(result.messages[0])
        return result.trajectory(0)

    def _until_terminated(self, result: "BatchResult") -> Trajectory:
        values = result.values[0]
        rows = rows_given(values)
        stopped = re.search(r"asked to terminate at t=(\S+?)(?::|$)", result.messages[0])
        when = f" at t={stopped.group(1)} s" if stopped else ""
        last = f"t={result.time[rows - 1]:g} s" if rows else "no output time"
        warnings.warn(f"{self.name} asked to terminate the simulation{when}, before the last output time "
                      f"{result.time[-1]:g} s: the trajectory ends at {last} ({rows} of {result.time.size} "
                      "output times)", ModelTerminated, stacklevel=3)
        return Trajectory(result.time[:rows].copy(), {n: values[:rows, j].copy() for j, n in enumerate(result.outputs)})

    def close(self) -> None:
        self._batches.clear()
        for r in self._runners.values():
            r.close()
        self._runners.clear()
        self.fmu.close()


class PreparedBatch:
    """What :meth:`Simulator.prepare` returns: call :meth:`run` with a value table."""

    def __init__(self, sim: Simulator, names: list[str], outputs: tuple[str, ...], times: np.ndarray, call,
                 held_inputs: Mapping[str, str] | None = None):
        times.flags.writeable = False  # shared by every result of the batch
        self.sim, self.names, self.outputs, self.time, self._call = sim, names, outputs, times, call
        self.held_inputs = dict(held_inputs or {})  # inputs not given -> the start value they are held at

    def run(self, values, check: bool = False) -> BatchResult:
        values = np.asarray(values, dtype=float)
        values = values.reshape(max(values.shape[0], 1) if values.ndim else 1, len(self.names))
        if check:
            for row in values:
                self.sim.check_parameters(dict(zip(self.names, row)))
        out, status, messages = self._call(values)
        described = tuple(m and f"{self.sim.name} failed with {_describe(dict(zip(self.names, row)))}: {m}"
                          for m, row in zip(messages, values))
        return BatchResult(self.time, self.outputs, out, np.asarray(status), described)


def _set_by_set(prepared, table: InputTable, names: list[str], default_delay: float):
    """A delayed bench's batch (:mod:`.delayed`): each set with the recording moved by its
    own delay, so each is prepared and run alone."""
    def call(values):
        delays = set_delays(names, values, default_delay)
        runs = [prepared(delayed_table(table, d))(values[i:i + 1]) for i, d in enumerate(delays)]
        if not runs:
            return prepared(table)(values)
        return (np.concatenate([r[0] for r in runs]), np.concatenate([np.asarray(r[1]) for r in runs]),
                [m for r in runs for m in r[2]])
    return call


def _content(value):
    """A hashable stand-in for a keyword of :meth:`Simulator.prepare` (see ``_prepared``)."""
    if value is None or isinstance(value, (str, int, float)):
        return value
    if isinstance(value, InputTable):
        return ("table", value.names, _content(value.time), _content(value.values))
    if isinstance(value, Mapping):
        return tuple((k, _content(v)) for k, v in value.items())
    array = np.asarray(value)
    if array.dtype == object:
        return tuple(map(_content, value))
    return (array.dtype.str, array.shape, hashlib.sha1(np.ascontiguousarray(array).data).digest())


def rows_given(values: np.ndarray) -> int:
    """How many leading output rows a set gave (a terminated set's outputs are NaN after
    them; the rows given are finite, as every runner checks)."""
    if values.shape[1] == 0:
        return values.shape[0]
    bad = np.flatnonzero(~np.all(np.isfinite(values), axis=1))
    return int(bad[0]) if bad.size else values.shape[0]


def _describe(params: Mapping[str, float]) -> str:
    return ", ".join(f"{k}={v:.6g}" for k, v in params.items()) or "default parameters"


_PREPARED_KEPT = 8  # prepared batches a simulator remembers (see Simulator._prepared)

# The package's only global state: per process, the simulators of the FMUs it has loaded.
_CACHE: dict[tuple, Simulator] = {}


def get_simulator(fmu: str | Path | FmuRef, *, timeout: float | None = None) -> Simulator:
    """The process's simulator for ``fmu``: loaded once, again only if the file changed."""
    key, path = cache_key(fmu)
    sim = _CACHE.get(key)
    if sim is None:
        for old in [k for k in _CACHE if k[0] == key[0] and k[0] != "sha256"]:
            _CACHE.pop(old).close()
        sim = _CACHE[key] = Simulator(path, timeout=timeout)
    sim.timeout = timeout
    return sim
