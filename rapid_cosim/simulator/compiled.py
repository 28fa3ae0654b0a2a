"""The compiled batch runner (``runner.c``): built once per machine, driven by ctypes.

The library is compiled with the system C compiler (``$CC``, default ``cc``, as the
embedded FMUs are) against the FMI 2.0 headers that fmpy ships, and cached by the hash
of its source, the compiler and the platform, under ``$RAPID_COSIM_CACHE`` (default
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
import hashlib
import os
import platform
import subprocess
from ctypes import POINTER, c_char_p, c_double, c_int, c_uint, c_void_p
from pathlib import Path

import fmpy
import numpy as np

from ..errors import BuildError, SimulationError
from .fmu import LoadedFmu
from .inputs import InputTable

SOURCE = Path(__file__).with_name("runner.c")

# Set status codes of runner.c
OK, SOLVER, FMI, NONFINITE, TIMEOUT, TERMINATED = range(6)
STATUS_NAMES = ("ok", "solver failure", "FMI error", "non-finite output", "time-out", "terminated by the model")


class _Batch(ctypes.Structure):
    _fields_ = [
        ("n_sets", c_int), ("n_params", c_int), ("param_vrs", POINTER(c_uint)), ("param_values", POINTER(c_double)),
        ("n_times", c_int), ("times", POINTER(c_double)),
        ("n_out", c_int), ("out_vrs", POINTER(c_uint)), ("out_types", POINTER(c_int)),
        ("n_inputs", c_int), ("input_vrs", POINTER(c_uint)), ("n_rows", c_int),
        ("input_time", POINTER(c_double)), ("input_values", POINTER(c_double)),
        ("start_time", c_double), ("timeout", c_double),
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
    from ..compiler.embedded import c_compiler, cache_dir  # one place says which compiler builds C here

    cc = c_compiler()
    source = SOURCE.read_bytes()
    key = hashlib.sha256(source + f"|{cc}|{platform.machine()}|{fmpy.__version__}".encode()).hexdigest()[:16]
    folder = cache_dir()
    lib = folder / f"rapid_cosim_runner-{key}{fmpy.sharedLibraryExtension}"
    if lib.exists():
        return lib
    folder.mkdir(parents=True, exist_ok=True)
    include = Path(fmpy.__file__).parent / "c-code"
    part = lib.with_name(f"{lib.name}.{os.getpid()}.part")
    cmd = [cc, "-std=c99", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", f"-I{include}", str(SOURCE),
           "-o", str(part), "-lm", "-ldl"]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True)
    except FileNotFoundError:
        raise BuildError(f"C compiler {cc!r} not found; the compiled runner needs one (install gcc or set CC), "
                         "or choose runner='python'") from None
    if proc.returncode != 0:
        part.unlink(missing_ok=True)
        raise BuildError(f"compiling the runner failed:\n{' '.join(cmd)}\n{proc.stderr[-4000:]}")
    os.replace(part, lib)
    return lib


_LIBRARY: ctypes.CDLL | None = None


def _library() -> ctypes.CDLL:
    global _LIBRARY
    if _LIBRARY is None:
        import fmpy.sundials  # noqa: F401  loads SUNDIALS, whose SONAMEs the runner's dlopen then finds

        lib = ctypes.CDLL(str(library_path()))
        lib.rc_open.restype = c_void_p
        lib.rc_open.argtypes = [c_char_p, c_char_p, c_char_p, c_char_p, c_int, c_int, c_double,
                                POINTER(c_char_p), c_char_p, c_int]
        lib.rc_close.argtypes = [c_void_p]
        lib.rc_close.restype = None
        lib.rc_run.argtypes = [c_void_p, POINTER(_Batch), POINTER(c_double), POINTER(c_int), POINTER(c_double),
                               c_char_p]
        lib.rc_run.restype = c_int
        lib.rc_msg_len.restype = c_int
        _LIBRARY = lib
    return _LIBRARY


def _ptr(a: np.ndarray, ctype):
    return a.ctypes.data_as(POINTER(ctype))


class CompiledRunner:
    """One FMU instance and one CVODE solver in C, for any number of batches."""

    def __init__(self, fmu: LoadedFmu, relative_tolerance: float):
        lib = _library()
        self.fmu = fmu
        self._lib = lib
        paths = (c_char_p * 5)(*[p.encode() for p in sundials_libraries()])
        err = ctypes.create_string_buffer(1024)
        md = fmu.model_description
        self._handle = lib.rc_open(str(fmu.binary).encode(), md.modelName.encode(), md.guid.encode(),
                                   fmu.resource_uri.encode(), fmu.n_states, fmu.n_event_indicators,
                                   relative_tolerance, paths, err, len(err))
        if not self._handle:
            raise SimulationError(f"{fmu.name}: the compiled runner could not open the FMU: {err.value.decode()}")
        self._msg_len = lib.rc_msg_len()

    def prepare(self, param_names: list[str], names: list[str], types: list[int], start_time: float,
                times: np.ndarray, inputs: InputTable | None, timeout: float | None) -> "PreparedRun":
        return PreparedRun(self, param_names, names, types, start_time, times, inputs, timeout)

    def close(self) -> None:
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
        b.n_sets, b.param_values = n, _ptr(values, c_double)
        out = np.empty((n, self.n_times, self.n_out))
        status = np.zeros(n, dtype=np.int32)
        reached = np.zeros(n)
        size = self.runner._msg_len
        messages = ctypes.create_string_buffer(size * max(n, 1))
        failed = self.runner._lib.rc_run(self.runner._handle, ctypes.byref(b), _ptr(out, c_double),
                                         _ptr(status, c_int), _ptr(reached, c_double), messages)
        texts = [""] * n
        if failed:
            raw = messages.raw
            texts = [raw[i * size:(i + 1) * size].split(b"\0", 1)[0].decode(errors="replace") for i in range(n)]
        return out, status, texts
