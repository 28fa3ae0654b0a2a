"""FMU -> trajectories.

``fmu`` checks and extracts an FMU; ``inputs`` holds input tables; ``compiled`` is the C
batch runner (the default) and ``reference`` the Python loop it is checked against;
``simulation`` puts them behind one :class:`Simulator` per FMU and process.
"""

from .fmu import FmuRef, LoadedFmu, ParameterInfo
from .inputs import InputTable
from .simulation import (DEFAULT_RUNNER, RUNNERS, BatchResult, Simulator, Trajectory, check_runner,
                         get_simulator, time_base)

__all__ = ["FmuRef", "LoadedFmu", "ParameterInfo", "InputTable", "DEFAULT_RUNNER", "RUNNERS", "BatchResult",
           "Simulator", "Trajectory", "check_runner", "get_simulator", "time_base"]
