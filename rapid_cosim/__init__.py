"""rapid-cosim: calibrate Modelica models of power-plant governors against staged tests.

The package follows the way data flows, each module knowing only those before it::

    modelica/iGrGen -> build -> simulator (integrator) -> data, experiment -> fitness
                    -> evaluate -> estimators -> archive -> staged, diagnose -> report -> cli

``errors`` and ``search`` (the search space and the scores of a batch, which the problem,
the evaluator and the estimators share) are leaves that import nothing from the package.
"""

__version__ = "0.1.0"
