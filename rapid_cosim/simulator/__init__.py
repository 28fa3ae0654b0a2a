"""FMU -> trajectories.

``fmu`` checks and extracts an FMU; ``inputs`` holds input tables; ``compiled`` drives the
C batch runners (CVODE, the default, and the exponential integrator of ``expint.c`` for
recorded inputs) and ``reference`` is the Python loop they are checked against;
``simulation`` puts them behind one :class:`Simulator` per FMU and process.
"""

from .fmu import FmuRef, LoadedFmu, ParameterInfo
from .inputs import InputTable
from .simulation import (DEFAULT_RUNNER, RUNNERS, BatchResult, Simulator, Trajectory, check_runner,
                         get_simulator, time_base)

__all__ = ["FmuRef", "LoadedFmu", "ParameterInfo", "InputTable", "DEFAULT_RUNNER", "RUNNERS", "BatchResult",
           "Simulator", "Trajectory", "check_runner", "get_simulator", "time_base"]
