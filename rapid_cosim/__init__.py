"""rapid-cosim: calibrate Modelica models of power-plant governors against field measurements.

The public API, in the manner of scipy.optimize::

    import rapid_cosim as rc
    fit = rc.calibrate(["experiments/test1"], method="pf:10+nm", seed=1)
    print(fit)                # the estimate, how it was found
    fit.plot("test1.png")     # measured and simulated, residuals beneath
    fit.to_frame()            # one row per parameter (pandas)

``calibrate``, ``resume``, ``rerun`` and ``load`` return one :class:`Calibration`;
``diagnose`` finds what a model misses; ``simulate`` runs one model or FMU; ``export``
writes a calibration of a standard governor as a PSS/E ``.dyr`` or PSLF ``.dyd`` record;
``identify`` delivers one unit's record, ``fleet`` checks and identifies many;
``check`` loads and checks what any of them would run on, before it runs;
:class:`Experiment` is made from a config file or in code. Where the models come from is
one :class:`ModelSource` (the package, its FMU folder, the compiler) and where the work
runs one :class:`EngineSpec` (workers, backend, scheduler), each passed down whole.

The package follows the way data flows, each module knowing only those before it
(``docs/architecture.md`` draws it; a test checks the imports)::

    modelica/iGrGen -> compiler -> simulator -> data -> noise -> experiment -> fitting
        -> estimators -> archive -> calibration -> diagnose -> structures -> identify
        -> report -> api -> fleet -> check -> cli

``errors`` and ``version`` are leaves; nothing inside imports this face.
"""

from .version import __version__  # noqa: E402

# The subpackages named as API functions are imported first: importing a subpackage for
# the first time binds its name here, and done later (inside rc.identify) it replaced the
# function with the module, so a second rc.identify(...) failed. (So the subpackages'
# modules are imported with ``from rapid_cosim.diagnose import selection``, not
# ``import rapid_cosim.diagnose.selection as ...``, which reads the name as the function.)
from . import diagnose as _diagnose, fleet as _fleet, identify as _identify  # noqa: E402, F401
from .api import Calibration, calibrate, diagnose, example, export, identify, load, rerun, resume, simulate  # noqa: E402
from .fleet import run_fleet as fleet  # noqa: E402
from .check import check  # noqa: E402
from .compiler.source import ModelSource  # noqa: E402
from .fitting.engine import EngineSpec  # noqa: E402
from .experiment import Experiment, experiment_from_arrays, experiment_from_frame, load_experiment  # noqa: E402
from .simulator import Trajectory  # noqa: E402

__all__ = ["Calibration", "EngineSpec", "Experiment", "ModelSource", "Trajectory", "experiment_from_arrays", "experiment_from_frame",
           "load_experiment", "calibrate", "check", "diagnose", "example", "export", "fleet", "identify", "load", "rerun", "resume",
           "simulate", "__version__"]
