"""FMU -> trajectories.

``fmu`` checks and extracts an FMU (FMI 2.0 or 3.0, Model Exchange or Co-Simulation);
``inputs`` holds input tables; ``compiled`` drives the C batch runners for Model Exchange
(CVODE, and the exponential integrator of ``expint.c``, the default) and ``reference`` is
the Python loop they are checked against; ``communication`` plans a Co-Simulation batch
and ``cosim`` runs it (a C driver, and the fmpy loop it is checked against);
``simulation`` puts them behind one :class:`Simulator` per FMU and process.
"""

from .fmu import FmuRef, LoadedFmu, ParameterInfo
from .inputs import InputTable
from .simulation import (DEFAULT_RUNNER, RUNNERS, BatchResult, Simulator, Trajectory, check_runner,
                         get_simulator, time_base)

__all__ = ["FmuRef", "LoadedFmu", "ParameterInfo", "InputTable", "DEFAULT_RUNNER", "RUNNERS", "BatchResult",
           "Simulator", "Trajectory", "check_runner", "get_simulator", "time_base"]
