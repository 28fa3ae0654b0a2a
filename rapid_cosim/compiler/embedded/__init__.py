"""The embedded Modelica-to-FMU path: pymoca front end, CasADi equations, an FMI 2.0 wrapper in C."""

import os
import tempfile
from pathlib import Path


def cache_dir() -> Path:
    """Where built artefacts shared by every folder and process of this user live: the
    compiled runner and the FMU cache. ``$RAPID_COSIM_CACHE``, else ``~/.cache/rapid-cosim``
    (or the temporary folder where the home is not writable)."""
    configured = os.environ.get("RAPID_COSIM_CACHE")
    if configured:
        return Path(configured)
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rapid-cosim"
    try:
        home.mkdir(parents=True, exist_ok=True)
        return home
    except OSError:
        return Path(tempfile.gettempdir()) / "rapid-cosim"


def c_compiler() -> str:
    """The compiler the embedded path uses; read in one place, as it is part of the FMUs' identity."""
    return os.environ.get("CC", "cc")
