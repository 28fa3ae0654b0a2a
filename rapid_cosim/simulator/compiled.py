"""The compiled batch runner (``runner.c``): built once per machine, driven by ctypes.

The library is compiled with the system C compiler (``$CC``, default ``cc``, as the
embedded FMUs are) against the FMI 2.0 headers that fmpy ships, and cached by the hash
of its source, the compiler and the platform, under ``$RAPID_COSIM_CACHE`` (default
``~/.cache/rapid-cosim``, or the temporary folder where the home is not writable). It
is built to a side file and renamed into place, so workers starting at once are safe.

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
import tempfile
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


def cache_dir() -> Path:
    configured = os.environ.get("RAPID_COSIM_CACHE")
    if configured:
        return Path(configured)
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rapid-cosim"
    try:
        home.mkdir(parents=True, exist_ok=True)
        return home
    except OSError:
        return Path(tempfile.gettempdir()) / "rapid-cosim"


def sundials_libraries() -> list[str]:
    """fmpy's SUNDIALS libraries in dependency order (core, nvector, matrix, solver, cvode)."""
    from fmpy.sundials import libraries

    folder = Path(libraries.library_dir)
    ext = fmpy.sharedLibraryExtension
    return [str(folder / f"sundials_{n}{ext}") for n in ("core", "nvecserial", "sunmatrixdense",
                                                           "sunlinsoldense", "cvode")]


def library_path() -> Path:
    """The runner library for this machine, compiled on first use."""
    from ..build.embedded import c_compiler  # one place says which compiler builds C here

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

    def run(self, param_names: list[str], values: np.ndarray, names: list[str], types: list[int],
            start_time: float, times: np.ndarray, inputs: InputTable | None, timeout: float | None):
        """(outputs (sets, times, names), status (sets,), times reached, messages)."""
        vr = self.fmu.value_references
        values = np.ascontiguousarray(values, dtype=float)  # (sets, parameters)
        n = values.shape[0]
        times = np.ascontiguousarray(times, dtype=float)
        param_vrs = np.array([vr[p] for p in param_names], dtype=np.uint32)
        out_vrs = np.array([vr[o] for o in names], dtype=np.uint32)
        out_types = np.array(types, dtype=np.int32)
        batch = _Batch(n_sets=n, n_params=len(param_names), param_vrs=_ptr(param_vrs, c_uint),
                       param_values=_ptr(values, c_double), n_times=times.size, times=_ptr(times, c_double),
                       n_out=len(names), out_vrs=_ptr(out_vrs, c_uint), out_types=_ptr(out_types, c_int),
                       start_time=start_time, timeout=timeout or 0.0)
        if inputs is not None:
            if len(inputs.names) > 64:
                raise SimulationError(f"{self.fmu.name}: the runner drives at most 64 inputs")
            input_vrs = np.array([vr[i] for i in inputs.names], dtype=np.uint32)
            batch.n_inputs, batch.input_vrs, batch.n_rows = len(inputs.names), _ptr(input_vrs, c_uint), inputs.time.size
            batch.input_time, batch.input_values = _ptr(inputs.time, c_double), _ptr(inputs.values, c_double)
        out = np.empty((n, times.size, len(names)))
        status = np.zeros(n, dtype=np.int32)
        reached = np.zeros(n)
        messages = ctypes.create_string_buffer(self._msg_len * max(n, 1))
        self._lib.rc_run(self._handle, ctypes.byref(batch), _ptr(out, c_double), _ptr(status, c_int),
                         _ptr(reached, c_double), messages)
        raw = messages.raw
        texts = [raw[i * self._msg_len:(i + 1) * self._msg_len].split(b"\0", 1)[0].decode(errors="replace")
                 for i in range(n)]
        return out, status, reached, texts

    def close(self) -> None:
        if self._handle:
            self._lib.rc_close(self._handle)
            self._handle = None

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass
