"""The embedded Modelica-to-FMU path: pymoca front end, CasADi equations, an FMI 2.0 wrapper in C."""

import hashlib
import os
import platform
import subprocess
import tempfile
import threading
from pathlib import Path
from typing import Sequence


def cache_dir() -> Path:
    """Where built artefacts shared by every folder and process of this user live: the
    compiled runner, the FMUs built for the shipped models and the FMU cache.
    ``$RAPID_COSIM_CACHE``, else the user's cache folder (platformdirs: ``~/.cache/rapid-cosim``
    on Linux), else the temporary folder where that cannot be written."""
    configured = os.environ.get("RAPID_COSIM_CACHE")
    if configured:
        return Path(configured)
    from platformdirs import user_cache_dir

    home = Path(user_cache_dir("rapid-cosim", appauthor=False))
    try:
        home.mkdir(parents=True, exist_ok=True)
        return home
    except OSError:
        return Path(tempfile.gettempdir()) / "rapid-cosim"


def c_compiler() -> str:
    """The compiler the embedded path uses; read in one place, as it is part of the FMUs' identity."""
    return os.environ.get("CC", "cc")


def shared_library(stem: str, sources: Sequence[Path], compile: Sequence[Path], flags: Sequence[str],
                   identity: str = "", what: str = "a compiled part", hint: str = "") -> Path:
    """A C library of this package built once per machine: ``compile`` compiled with
    ``flags`` by :func:`c_compiler` into :func:`cache_dir`, named by the hash of
    ``sources`` (every file it reads), the compiler and its flags, the platform and
    ``identity``. Built to a side file and renamed into place, so processes and threads
    starting at once are safe."""
    import fmpy

    from ...errors import BuildError

    cc = c_compiler()
    source = b"".join(Path(p).read_bytes() for p in sources)
    base = [cc, "-std=c99", "-O2", "-fPIC", "-shared", "-fvisibility=hidden"]
    how = " ".join([*base, *flags])  # the flags too: a library built with others is another library
    key = hashlib.sha256(source + f"|{how}|{platform.machine()}|{identity}".encode()).hexdigest()[:16]
    folder = cache_dir()
    lib = folder / f"{stem}-{key}{fmpy.sharedLibraryExtension}"
    if lib.exists():
        return lib
    folder.mkdir(parents=True, exist_ok=True)
    part = lib.with_name(f"{lib.name}.{os.getpid()}.{threading.get_ident()}.part")  # threads of one process too
    cmd = [*base, *map(str, compile), *flags, "-o", str(part)]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True)
    except FileNotFoundError:
        raise BuildError(f"C compiler {cc!r} not found; {what} needs one (install gcc or set CC){hint}") from None
    if proc.returncode != 0:
        part.unlink(missing_ok=True)
        raise BuildError(f"compiling {what} failed:\n{' '.join(cmd)}\n{proc.stderr[-4000:]}")
    os.replace(part, lib)
    return lib
