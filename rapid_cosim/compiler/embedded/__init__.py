"""The embedded Modelica-to-FMU path: pymoca front end, CasADi equations, an FMI 2.0 wrapper in C."""

import os
import tempfile
from pathlib import Path


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
