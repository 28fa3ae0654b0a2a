"""The embedded Modelica-to-FMU path: pymoca front end, CasADi equations, an FMI 2.0 wrapper in C."""

import os


def c_compiler() -> str:
    """The compiler the embedded path uses; read in one place, as it is part of the FMUs' identity."""
    return os.environ.get("CC", "cc")
