"""Experiments: ``definition`` (the :class:`Experiment` object and its parts), ``config``
(the TOML schema and reader), ``toml_writer`` (configs written by programs)."""

from .config import config_key, load_experiment, parse_experiment
from .definition import (CONFIG_NAME, DEFAULT_TIMEOUT, NOISE_PRE_STEP, SCALES, EstimateSpec, Experiment,
                         ScoredSamples, SimulationSettings)
from .toml_writer import render_config

__all__ = ["config_key", "load_experiment", "parse_experiment", "CONFIG_NAME", "DEFAULT_TIMEOUT", "NOISE_PRE_STEP",
           "SCALES", "EstimateSpec", "Experiment", "ScoredSamples", "SimulationSettings", "render_config"]
