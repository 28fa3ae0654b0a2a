"""Electrical power at the terminals: what a config that declares it must also give, and
what the ROCOF input costs the fitness.

A plant records P_e, not P_m; the recorded-frequency benches have both outputs (``pm``,
``pe``: iGrGen.Machines.SwingPower, P_e = P_m - w (2 H dw/dt + D (w - 1))). A config says
which one its power column is by the output's name::

    [data]
    outputs = { pe = { column = "P", unit = "MW", rating = 900.0 } }
    [fixed]
    "mach.H" = 6.5          # or [estimate] "mach.H" = { min = 2.0, max = 12.0 }

``pm`` stays the default meaning of existing configs. Declaring ``pe`` without the
inertia constant is an error, never a silent P_m: H decides how much of the recording
is the rotor's. MW (kW, W, GW) without the unit's rating is an error too: it would be
compared with per-unit power. The ranges are those of the Modelica parameters
(``H_RANGE``, ``D_RANGE``; a test checks the FMU declares the same).

ROCOF: the bench's input ``rocof`` (Hz/s) comes from a ROCOF column, checked against the
frequency's own derivative (a wrong sign or unit is an error), or is derived from the
frequency (:mod:`rapid_cosim.simulator.rocof`). Its noise reaches P_e as
2 H / f_nom x the ROCOF's noise, which the recorder's power noise does not contain; it is
measured on the quiet pre-event samples and added to the fitness's noise of ``pe``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..errors import ConfigError
from ..simulator.rocof import FREQUENCY, ROCOF, WINDOW, derive_rocof
from .toml_writer import config_key

ELECTRICAL = "pe"
INERTIA = "mach.H"
DAMPING = "mach.D"
H_RANGE = (0.5, 15.0)  # s, as Machines.SwingPower.H
D_RANGE = (0.0, 5.0)  # pu, as Machines.SwingPower.D
POWER_UNITS = ("MW", "kW", "W", "GW")
ROCOF_RATIO = (0.5, 2.0)  # a ROCOF column against the frequency's derivative


def check_rating(spec: dict, cfg, key: str) -> float | None:
    """The scale of an output from its ``rating`` (MVA): 1 / rating. A power in MW (kW,
    W, GW) needs a rating or a scale: without one it would be compared as per unit."""
    unit = spec.get("unit", "")
    if "rating" in spec:
        if "scale" in spec:
            raise ConfigError("give rating (MVA) or scale, not both", cfg.file, f"{key}.rating")
        rating = cfg.number(spec["rating"], f"{key}.rating")
        if not rating > 0:
            raise ConfigError(f"rating must be the unit's MVA rating, > 0; got {rating:g}", cfg.file, f"{key}.rating")
        if unit not in POWER_UNITS:
            raise ConfigError(f"a rating converts a power in {', '.join(POWER_UNITS)}; unit is {unit!r}",
                              cfg.file, f"{key}.unit")
        return 1.0 / rating
    if unit in POWER_UNITS and "scale" not in spec:
        raise ConfigError(f"power in {unit} needs the unit's rating to become per unit (rating = 900.0, MVA; "
                          f"or scale = 1 / rating); allowed: rating > 0", cfg.file, key)
    return None


def check_machine(outputs: dict[str, str], fixed: dict[str, float], estimate, cfg) -> None:
    """Electrical power declared: H given (fixed or estimated) and every machine constant
    inside its range."""
    bounds = {s.name: s for s in estimate}
    if ELECTRICAL in outputs and INERTIA not in fixed and INERTIA not in bounds:
        raise ConfigError(f"electrical power (output {ELECTRICAL}) needs the unit's inertia constant H: fix it "
                          f"([fixed] \"{INERTIA}\" = 6.5, documented) or estimate it ([estimate] \"{INERTIA}\" = "
                          f"{{ min = 2.0, max = 12.0 }}); allowed {H_RANGE[0]:g} to {H_RANGE[1]:g} s",
                          cfg.file, config_key("data.outputs", ELECTRICAL))
    for name, (lo, hi), unit in ((INERTIA, H_RANGE, "s"), (DAMPING, D_RANGE, "pu")):
        if name in fixed and not lo <= fixed[name] <= hi:
            raise ConfigError(f"{name} = {fixed[name]:g} {unit} is outside the allowed {lo:g} to {hi:g} {unit}",
                              cfg.file, config_key("fixed", name))
        if name in bounds:
            spec = bounds[name]
            for end, value in (("min", spec.min), ("max", spec.max)):
                if not lo <= value <= hi:
                    raise ConfigError(f"{name} {end} = {value:g} {unit} is outside the allowed {lo:g} to {hi:g} "
                                      f"{unit}", cfg.file, f"{config_key('estimate', name)}.{end}")


def model_rocof(exp) -> np.ndarray | None:
    """The ROCOF the bench sees on the input table's rows, or None without a frequency input."""
    table = exp.input_table  # given, or derived there (split at the event)
    if table is None or ROCOF not in table.names:
        return None
    return table.values[:, table.names.index(ROCOF)]


def check_rocof_column(exp, cfg) -> None:
    """A ROCOF column must be the frequency's derivative: its least-squares ratio to the
    derived one within ROCOF_RATIO (a wrong sign gives -1, mHz/s read as Hz/s 1000, rad/s^2
    2 pi, pu/s 1 / f_nom). Checked only where the frequency moves well beyond its noise."""
    spec = next((s for s in exp.inputs if s.name == ROCOF and s.column), None)
    table = exp.input_table
    if spec is None or table is None or FREQUENCY not in table.names:
        return
    given = table.values[:, table.names.index(ROCOF)]
    breaks = () if exp.pre_step_end is None else (exp.pre_step_end,)
    derived = derive_rocof(table.time, table.values[:, table.names.index(FREQUENCY)], WINDOW, breaks)
    quiet = table.time < exp.pre_step_end if exp.pre_step_end is not None else np.zeros(table.time.size, bool)
    noise = float(np.std(derived[quiet])) if quiet.sum() > 10 else 0.0
    if np.sqrt(np.mean(derived ** 2)) <= 5.0 * noise or not np.any(derived):
        return  # the frequency hardly moves: nothing to compare
    ratio = float(np.dot(given, derived) / np.dot(derived, derived))
    lo, hi = ROCOF_RATIO
    if not lo <= ratio <= hi:
        why = "a wrong sign" if ratio < 0 else "a wrong unit (mHz/s read as Hz/s: 1000; rad/s^2: 6.28; pu/s: 1/f_nom)"
        raise ConfigError(f"column '{spec.column}' is {ratio:.3g} times the derivative of the frequency "
                          f"(f_dev): {why}? allowed {lo:g} to {hi:g}", cfg.file, config_key("inputs", ROCOF))


def rocof_component(exp) -> tuple[float, float] | None:
    """The derived ROCOF's noise in the bench's ``pe`` as a slow component (sigma in pu,
    correlation time in s): 2 H / f_nom times the ROCOF's spread over the quiet pre-event
    samples (H fixed, or the top of its bounds when estimated: the noise is not
    underestimated), correlated over about half the filter's window; None without it."""
    if ELECTRICAL not in exp.outputs or exp.pre_step_end is None:
        return None
    rocof = model_rocof(exp)
    if rocof is None:
        return None
    quiet = exp.input_table.time < exp.pre_step_end
    if quiet.sum() < 10:
        return None
    bounds = {s.name: s.max for s in exp.estimate}
    h = exp.fixed.get(INERTIA, bounds.get(INERTIA))
    extra = 2.0 * h / exp.fixed.get("f_nom", 50.0) * float(np.std(rocof[quiet]))
    return (extra, WINDOW / 2) if extra > 0 else None


def with_rocof_noise(exp):
    """``exp`` with the ROCOF's noise (:func:`rocof_component`) added to the noise of
    ``pe``: to its sigma, and to its noise model as a slow component. The recorder's
    noise, estimated from the recorded power, does not contain it; a diagnosis's null
    adds it too (:mod:`rapid_cosim.diagnose.null`)."""
    component = rocof_component(exp)
    if component is None:
        return exp
    extra = component[0]
    sigma = exp.noise_sigma
    if sigma is not None and ELECTRICAL in sigma:
        sigma = {**sigma, ELECTRICAL: math.hypot(sigma[ELECTRICAL], extra)}
    models = dict(exp.noise_models)
    if ELECTRICAL in models:
        m = models[ELECTRICAL]
        models[ELECTRICAL] = replace(m, components=m.components + (component,))
    return replace(exp, noise_sigma=sigma, noise_models=models)
