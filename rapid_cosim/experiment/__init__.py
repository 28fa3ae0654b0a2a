"""Experiments: ``definition`` (the :class:`Experiment` object and its parts), ``spec``
(a config read and checked without its recordings), ``config`` (the TOML schema and the
loader of a spec's recordings), ``reader`` (typed access to a parsed config), ``construct`` (experiments made in code), ``toml_writer``
(configs written by programs)."""

from .config import config_key, load_experiment, parse_experiment
from .construct import experiment_from_arrays, experiment_from_frame
from .definition import (CONFIG_NAME, DEFAULT_TIMEOUT, NOISE_PRE_STEP, SCALES, EstimateSpec, Experiment,
                         ScoredSamples, SimulationSettings)
from .toml_writer import render_config

__all__ = ["config_key", "load_experiment", "parse_experiment", "CONFIG_NAME", "DEFAULT_TIMEOUT", "NOISE_PRE_STEP",
           "SCALES", "EstimateSpec", "Experiment", "ScoredSamples", "SimulationSettings", "render_config",
           "experiment_from_arrays", "experiment_from_frame"]
