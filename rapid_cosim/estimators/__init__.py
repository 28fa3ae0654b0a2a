"""Estimators: particle filter, SMC, PSO, Nelder-Mead, gradient descent, a coordinate
scan and multistart least squares (Levenberg-Marquardt from a Sobol design), each a plain function ``method(objective, space, *, options, rng, callback, x0)``
returning one :class:`EstimationResult`, and :func:`run_chain` to run them in sequence
from a method string such as ``"pf:10+nm"``."""

from .base import (EstimationResult, Evaluations, Iteration, IterationCallback, Objective,
                   SearchSpace)
from .chain import REGISTRY, Stage, parse_method, run_chain
from .gradient import GDOptions, gradient_descent
from .lm import LMOptions
from .multistart import MSOptions, multistart, reached_best
from .nelder_mead import NMOptions, nelder_mead
from .pf import PFOptions, particle_filter
from .pso import PSOOptions, pso
from .scan import ScanOptions, coordinate_scan
from .smc import SMCOptions, smc
from .uncertainty import Uncertainty

__all__ = [
    "EstimationResult", "Evaluations", "Iteration", "IterationCallback", "Objective",
    "SearchSpace", "Uncertainty",
    "REGISTRY", "Stage", "parse_method", "run_chain",
    "GDOptions", "gradient_descent",
    "LMOptions", "MSOptions", "multistart", "reached_best",
    "NMOptions", "nelder_mead",
    "PFOptions", "particle_filter",
    "PSOOptions", "pso",
    "ScanOptions", "coordinate_scan",
    "SMCOptions", "smc",
]
