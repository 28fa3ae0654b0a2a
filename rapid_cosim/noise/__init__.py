"""The recorder's noise model: what quiet data show, fitted once per recorder and used
everywhere a residual is judged (prewhitening, the fitness weighting, the criterion, the
intervals and the adequacy null).

``model`` holds :class:`RecorderNoise` (white + slow Ornstein-Uhlenbeck components: its
whitening, simulation and autocorrelation), ``quiet`` finds the stretches where a
recording holds only noise, ``estimate`` fits the model to them by REML, with its
uncertainty, and picks the family by BIC.
"""

from .estimate import NoiseFit, campaign_noise, fit_noise, model_acf, noise_models, pooled_acf
from .model import FAMILIES, RecorderNoise, Whitener, sample_draws
from .runs import runs
from .quiet import QuietStretch, quiet_stretches, quiet_windows, recorder_groups

__all__ = ["FAMILIES", "NoiseFit", "QuietStretch", "RecorderNoise", "Whitener", "campaign_noise", "fit_noise",
           "model_acf", "noise_models", "pooled_acf", "quiet_stretches", "quiet_windows", "recorder_groups",
           "runs", "sample_draws"]
