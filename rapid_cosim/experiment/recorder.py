"""The ``[noise]`` section: the recorder's noise model of each compared output.

    [noise.pm]                     # the output it describes
    white = 0.00118                # standard deviation of the white part (pu); 0: none
    dt = 0.1                       # the recorder's nominal sample interval (s)
    components = [{ sigma = 0.00076, tau = 0.9 }]   # slow parts: std (pu), correlation time (s)

With it the fitness is the generalised least squares of the residuals whitened by that
model (:mod:`rapid_cosim.fitting.fitness`), so correlated noise is not counted as evidence. The
diagnosis writes it into its candidates' configs from the quiet data
(:mod:`rapid_cosim.noise`); a user may give it too.
"""

from __future__ import annotations

import numpy as np

from ..data import MeasuredData
from ..errors import ConfigError
from ..noise import RecorderNoise
from .schema import NOISE_COMPONENT, NOISE_MODEL
from .toml_writer import config_key

_KEYS = NOISE_MODEL.names
DT_TOLERANCE = 0.1  # the model's dt may differ this much (relative) from the data's median interval


def read_noise_models(table: dict, outputs: dict[str, str], weights: dict[str, float], data: MeasuredData,
                      cfg) -> dict[str, RecorderNoise]:
    """One :class:`RecorderNoise` per output named in ``[noise]``; every output of
    positive weight needs one if any has."""
    models: dict[str, RecorderNoise] = {}
    for out, spec in table.items():
        key = config_key("noise", out)
        if out not in outputs:
            raise ConfigError(f"'{out}' is not an output of [data.outputs] ({', '.join(outputs)})", cfg.file, key)
        spec = cfg.table(spec, key)
        cfg.check_keys(spec, _KEYS, key)
        white = cfg.number(spec.get("white", 0.0), f"{key}.white")
        if white < 0:
            raise ConfigError(f"must be >= 0 (pu), got {white:g}", cfg.file, f"{key}.white")
        dt = cfg.number(cfg.require(spec, key, "dt"), f"{key}.dt")
        column = outputs[out]
        t = data.time[data.valid[column]]
        median = float(np.median(np.diff(t))) if t.size > 1 else dt
        if not abs(dt - median) <= DT_TOLERANCE * median:
            raise ConfigError(f"dt = {dt:g} s, but the recording's median sample interval is {median:g} s; "
                              "the noise model describes one recorder's samples", cfg.file, f"{key}.dt")
        comps = spec.get("components", [])
        if not isinstance(comps, list):
            raise ConfigError(f"expected a list of {{ sigma = ..., tau = ... }}, got {comps!r}", cfg.file,
                              f"{key}.components")
        pairs = []
        for k, c in enumerate(comps):
            ckey = f"{key}.components[{k}]"
            c = cfg.table(c, ckey)
            cfg.check_keys(c, NOISE_COMPONENT.names, ckey)
            sigma = cfg.number(cfg.require(c, ckey, "sigma"), f"{ckey}.sigma")
            tau = cfg.number(cfg.require(c, ckey, "tau"), f"{ckey}.tau")
            if not sigma > 0 or not tau > 0:
                raise ConfigError(f"sigma (pu) and tau (s) must be positive, got sigma = {sigma:g}, tau = {tau:g}",
                                  cfg.file, ckey)
            pairs.append((sigma, tau))
        if white == 0 and not pairs:
            raise ConfigError("a noise model needs a white part or a slow component", cfg.file, key)
        models[out] = RecorderNoise(white, tuple(pairs), dt)
    if models:
        missing = [o for o, w in weights.items() if w > 0 and o not in models]
        if missing:
            raise ConfigError(f"no noise model for output(s) {', '.join(missing)}: with [noise] every compared "
                              "output needs one", cfg.file, "noise")
    return models
