"""The compiled batch runners (``runner.c``, ``expint.c``, ``cosim.c``): built once per
machine, driven by ctypes.

One library holds them: ``expint.c`` (the exponential integrator of the "exponential"
runner) includes ``runner.c`` (CVODE, the "compiled" runner), whose path it falls back
to, so the two are one translation unit and ``runner.c``'s code is compiled unchanged;
``cosim.c``, the Co-Simulation driver (see :mod:`.cosim`), is a second one. Both read FMI
3.0 FMUs through ``fmi3_table.h``. The library is compiled with the system C compiler
(``$CC``, default ``cc``, as the embedded FMUs are) against the FMI 2.0 and 3.0 headers
that fmpy ships, and cached by the hash
of its sources, the compiler and the platform, under ``$RAPID_COSIM_CACHE`` (default
``~/.cache/rapid-cosim``, or the temporary folder where the home is not writable). It
is built to a side file and renamed into place, so workers starting at once are safe
(``rapid_cosim.compiler.embedded.cache_dir``).

SUNDIALS: the runner uses the CVODE build that fmpy ships (SUNDIALS 7.5 in fmpy 0.3.32,
pinned). That is the same binary the Python reference loop runs, so the two paths do the
same arithmetic (bit for bit on the test benches); it is maintained with fmpy and comes
with it, so a fresh machine needs nothing beyond ``pip install``. The alternatives were
weighed: Debian's ``libsundials-dev`` (6.4 on bookworm) needs root and apt on every
user's machine, and the ``sundials4py`` wheel would put a second, different CVODE beside
fmpy's. fmpy does not ship SUNDIALS headers, so ``runner.c`` declares the few functions
it uses from the SUNDIALS 7 API and checks the library's version when it opens.
"""

from __future__ import annotations

import ctypes
import weakref
from ctypes import POINTER, c_char_p, c_double, c_int, c_uint, c_void_p
from pathlib import Path

import fmpy
import numpy as np

from ..errors import SimulationError
from .fmu import LoadedFmu
from .inputs import InputTable

SOURCE = Path(__file__).with_name("expint.c")  # includes runner.c
COSIM_SOURCE = Path(__file__).with_name("cosim.c")
SOURCES = (Path(__file__).with_name("runner.c"), SOURCE, COSIM_SOURCE, Path(__file__).with_name("fmi3_table.h"))

# Set status codes of runner.c
OK, SOLVER, FMI, NONFINITE, TIMEOUT, TERMINATED = range(6)
STATUS_NAMES = ("ok", "solver failure", "FMI error", "non-finite output", "time-out", "terminated by the model")


class _Batch(ctypes.Structure):
    _fields_ = [
        ("n_sets", c_int), ("n_params", c_int), ("param_vrs", POINTER(c_uint)), ("param_values", c_void_p),
        ("n_times", c_int), ("times", POINTER(c_double)),
        ("n_out", c_int), ("out_vrs", POINTER(c_uint)), ("out_types", POINTER(c_int)),
        ("n_inputs", c_int), ("input_vrs", POINTER(c_uint)), ("n_rows", c_int),
        ("input_time", POINTER(c_double)), ("input_values", POINTER(c_double)),
        ("start_time", c_double), ("timeout", c_double), ("out_elem", POINTER(c_int)),
        ("param_types", POINTER(c_int)),
    ]


def sundials_libraries() -> list[str]:
    """fmpy's SUNDIALS libraries in dependency order (core, nvector, matrix, solver, cvode)."""
    from fmpy.sundials import libraries

    folder = Path(libraries.library_dir)
    ext = fmpy.sharedLibraryExtension
    return [str(folder / f"sundials_{n}{ext}") for n in ("core", "nvecserial", "sunmatrixdense",
                                                           "sunlinsoldense", "cvode")]


def library_path() -> Path:
    """The runner library for this machine, compiled on first use."""
    from ..compiler.embedded import shared_library  # one place says which compiler builds C here

    include = Path(fmpy.__file__).parent / "c-code"
    return shared_library("rapid_cosim_runner", SOURCES, (SOURCE, COSIM_SOURCE),
                          (f"-I{include}", "-lm", "-ldl"), identity=fmpy.__version__,
                          what="the compiled runner", hint=", or choose runner='python'")


_LIBRARY: ctypes.CDLL | None = None


def _library() -> ctypes.CDLL:
    global _LIBRARY
    if _LIBRARY is None:
        import fmpy.sundials  # noqa: F401  loads SUNDIALS, whose SONAMEs the runner's dlopen then finds

        lib = ctypes.CDLL(str(library_path()))
        lib.rc_open.restype = c_void_p
        lib.rc_open.argtypes = [c_char_p, c_char_p, c_char_p, c_char_p, c_int, c_int, c_double,
                                POINTER(c_char_p), c_char_p, c_int, c_int]
        lib.rc_close.argtypes = [c_void_p]
        lib.rc_close.restype = None
        # arrays go by address (see _address): converting them to ctypes pointers costs a
        # good part of a short simulation
        lib.rc_run.argtypes = [c_void_p, c_void_p, c_void_p, c_void_p, c_void_p, c_void_p]
        lib.rc_run.restype = c_int
        lib.rc_msg_len.restype = c_int
        lib.rc_plan_new.restype = c_void_p
        lib.rc_plan_new.argtypes = [c_void_p, POINTER(_Batch), POINTER(c_uint), c_char_p, c_int]
        lib.rc_plan_free.argtypes = [c_void_p]
        lib.rc_plan_free.restype = None
        lib.rc_run_exp.argtypes = [c_void_p, c_void_p, c_void_p, c_void_p, c_void_p, c_void_p, c_void_p]
        lib.rc_run_exp.restype = c_int
        lib.rc_plan_counters.argtypes = [c_void_p, POINTER(ctypes.c_longlong)]
        lib.rc_plan_counters.restype = c_int
        lib.rc_mat_mul.argtypes = [c_int, c_void_p, c_void_p, c_void_p, c_int]
        lib.rc_mat_mul.restype = None
        lib.cs_open.restype = c_void_p
        lib.cs_open.argtypes = [c_char_p, c_char_p, c_char_p, c_char_p, c_int, c_int, POINTER(c_uint), c_int,
                                c_char_p, c_int]
        lib.cs_close.argtypes = [c_void_p]
        lib.cs_close.restype = None
        lib.cs_run.argtypes = [c_void_p, c_void_p, c_void_p, c_void_p, c_void_p, c_void_p]
        lib.cs_run.restype = c_int
        lib.cs_msg_len.restype = c_int
        _LIBRARY = lib
    return _LIBRARY


def _ptr(a: np.ndarray, ctype):
    return a.ctypes.data_as(POINTER(ctype))


def _address(a: np.ndarray) -> int:
    """The address of a C-contiguous array's data: through ctypes.from_buffer, three times
    quicker than ``a.ctypes.data`` (a few microseconds a call matter for short runs); read-only
    arrays take the slow way."""
    try:
        return ctypes.addressof(ctypes.c_char.from_buffer(a))
    except (TypeError, ValueError):
        return a.ctypes.data


class CompiledRunner:
    """One FMU instance and one CVODE solver in C, for any number of batches;
    ``method="exponential"`` runs them with the exponential integrator of ``expint.c``
    (CVODE where it does not apply)."""

    def __init__(self, fmu: LoadedFmu, relative_tolerance: float, method: str = "cvode"):
        lib = _library()
        self.fmu = fmu
        self._lib = lib
        paths = (c_char_p * 5)(*[p.encode() for p in sundials_libraries()])
        err = ctypes.create_string_buffer(1024)
        md = fmu.model_description
        self._handle = lib.rc_open(str(fmu.binary).encode(), md.modelName.encode(), md.guid.encode(),
                                   fmu.resource_location.encode(), fmu.n_states, fmu.n_event_indicators,
                                   relative_tolerance, paths, err, len(err), 3 if fmu.fmi3 else 2)
        if not self._handle:
            raise SimulationError(f"{fmu.name}: the compiled runner could not open the FMU: {err.value.decode()}")
        self._msg_len = lib.rc_msg_len()
        self.method = method
        self._plans: set[int] = set()  # exponential plans on this handle, freed before it is

    def _new_plan(self, batch: "_Batch", der_vrs: np.ndarray | None) -> int:
        err = ctypes.create_string_buffer(256)
        plan = self._lib.rc_plan_new(self._handle, ctypes.byref(batch),
                                     None if der_vrs is None else _ptr(der_vrs, c_uint), err, len(err))
        if not plan:
            raise SimulationError(f"{self.fmu.name}: the exponential runner could not plan the batch: "
                                  f"{err.value.decode()}")
        self._plans.add(plan)
        return plan

    def _free_plan(self, plan: int) -> None:
        if plan in self._plans:
            self._plans.remove(plan)
            self._lib.rc_plan_free(plan)

    def prepare(self, param_names: list[str], names: list[str], types: list[int], start_time: float,
                times: np.ndarray, inputs: InputTable | None, timeout: float | None) -> "PreparedRun":
        kind = ExponentialRun if self.method == "exponential" else PreparedRun
        return kind(self, param_names, names, types, start_time, times, inputs, timeout)

    def close(self) -> None:
        for plan in list(getattr(self, "_plans", ())):
            self._free_plan(plan)
        if self._handle:
            self._lib.rc_close(self._handle)
            self._handle = None

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


class PreparedRun:
    """A batch whose shape is fixed (parameters set, outputs, times, inputs): the C
    structure is filled once, each call only points it at new values."""

    def __init__(self, runner: CompiledRunner, param_names, names, types, start_time, times, inputs, timeout):
        vr = runner.fmu.value_references
        self.runner = runner
        self._keep = [np.array([vr[p] for p in param_names], dtype=np.uint32),
                      np.ascontiguousarray(times, dtype=float), np.array([vr[o] for o in names], dtype=np.uint32),
                      np.array(types, dtype=np.int32)]
        self.n_params, self.n_times, self.n_out = len(param_names), len(self._keep[1]), len(names)
        b = self._batch = _Batch(n_params=self.n_params, param_vrs=_ptr(self._keep[0], c_uint), n_times=self.n_times,
                                 times=_ptr(self._keep[1], c_double), n_out=self.n_out,
                                 out_vrs=_ptr(self._keep[2], c_uint), out_types=_ptr(self._keep[3], c_int),
                                 start_time=start_time, timeout=timeout or 0.0)
        elements = runner.fmu.output_elements(names)
        if elements is not None:
            self._keep.append(elements)
            b.out_elem = _ptr(elements, c_int)
        kinds = runner.fmu.parameter_types(param_names)
        if kinds is not None:
            self._keep.append(kinds)
            b.param_types = _ptr(kinds, c_int)
        if inputs is not None:
            if len(inputs.names) > 64:
                raise SimulationError(f"{runner.fmu.name}: the runner drives at most 64 inputs")
            input_vrs = np.array([vr[i] for i in inputs.names], dtype=np.uint32)
            self._keep += [input_vrs, inputs]
            b.n_inputs, b.input_vrs, b.n_rows = len(inputs.names), _ptr(input_vrs, c_uint), inputs.time.size
            b.input_time, b.input_values = _ptr(inputs.time, c_double), _ptr(inputs.values, c_double)

    def __call__(self, values: np.ndarray):
        """(outputs (sets, times, outputs), status (sets,), messages) for the rows of ``values``."""
        if not self.runner._handle:
            raise SimulationError(f"{self.runner.fmu.name}: the runner was closed (the FMU was reloaded)")
        values = np.ascontiguousarray(values, dtype=float)
        n = values.shape[0]
        b = self._batch
        b.n_sets, b.param_values = n, _address(values) if values.size else None
        out = np.empty((n, self.n_times, self.n_out))
        status = np.zeros(n, dtype=np.int32)
        reached = np.empty(n)
        size = self.runner._msg_len
        if self._messages is None or len(self._messages) < size * max(n, 1):
            self._messages = ctypes.create_string_buffer(size * max(n, 1))
        messages = self._messages
        failed = self._run(_address(out) if out.size else None, _address(status), _address(reached),
                           ctypes.addressof(messages))
        texts = [""] * n
        if failed:
            raw = messages.raw
            texts = [raw[i * size:(i + 1) * size].split(b"\0", 1)[0].decode(errors="replace") for i in range(n)]
        return out, status, texts

    _messages = None  # the message buffer, kept from call to call

    def _run(self, out: int, status: int, reached: int, messages: int) -> int:
        return self.runner._lib.rc_run(self.runner._handle, self._batch_address, out, status, reached, messages)

    @property
    def _batch_address(self) -> int:
        return ctypes.addressof(self._batch)


# What rc_plan_counters reports, in its order (expint.c's EX_SETS ...).
COUNTERS = ("sets", "sets_cvode", "switched_to_cvode", "steps", "evaluations", "misses", "corrected",
            "cvode_intervals", "relinearisations")


class ExponentialRun(PreparedRun):
    """A prepared batch run by ``expint.c``'s exponential integrator. Its plan (the grid
    of output times and input rows, the integrator's work space) is made once here.

    ``counters`` says what the integrator did over the calls so far: sets it ran and sets
    it left to CVODE, steps, model evaluations, steps whose error estimate missed, and
    how they were mended."""

    def __init__(self, runner: CompiledRunner, *args):
        super().__init__(runner, *args)
        fmu = runner.fmu
        vr = fmu.value_references
        ders = [d.variable.name for d in fmu.model_description.derivatives]
        der_vrs = np.array([vr[d] for d in ders], dtype=np.uint32) if len(ders) == fmu.n_states else None
        self._keep.append(der_vrs)
        if not runner._handle:
            raise SimulationError(f"{fmu.name}: the runner was closed (the FMU was reloaded)")
        self._plan = runner._new_plan(self._batch, der_vrs)
        weakref.finalize(self, runner._free_plan, self._plan)

    def _run(self, out: int, status: int, reached: int, messages: int) -> int:
        runner = self.runner
        if self._plan not in runner._plans:
            raise SimulationError(f"{runner.fmu.name}: the runner was closed (the FMU was reloaded)")
        failed = runner._lib.rc_run_exp(runner._handle, ctypes.addressof(self._batch), self._plan, out, status,
                                        reached, messages)
        if failed == -2:  # the plan is not the batch's: a bug, not a set's failure
            raise SimulationError(f"{runner.fmu.name}: the exponential runner's plan does not fit the batch")
        return failed

    @property
    def counters(self) -> dict[str, int]:
        """What the integrator did over the calls so far (see ``COUNTERS``)."""
        counts = (ctypes.c_longlong * len(COUNTERS))()
        if self._plan in self.runner._plans:
            self.runner._lib.rc_plan_counters(self._plan, counts)
        return dict(zip(COUNTERS, counts))
