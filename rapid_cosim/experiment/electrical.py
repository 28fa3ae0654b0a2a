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
2 H / f_nom x the ROCOF's noise, which the recorder's power noise does not contain: the
frequency recorder's noise model, fitted to the quiet pre-event samples (by moments), through the
derivative filter (:class:`rapid_cosim.noise.filtered.FilteredNoise`, band-pass, whitened
exactly from its autocovariance), joins the fitness's noise model of ``pe``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from scipy import sparse
from scipy.signal import savgol_coeffs

from ..errors import ConfigError
from ..noise import QuietStretch, RecorderNoise
from ..noise.estimate import moment_noise
from ..noise.filtered import FilteredNoise
from ..noise.timed import DerivedNoise
from ..simulator.rocof import FREQUENCY, ORDER, ROCOF, WINDOW, points, rocof_operator
from .toml_writer import config_key

ELECTRICAL = "pe"
INERTIA = "mach.H"
DAMPING = "mach.D"
H_RANGE = (0.5, 15.0)  # s, as Machines.SwingPower.H
D_RANGE = (0.0, 5.0)  # pu, as Machines.SwingPower.D
POWER_UNITS = ("MW", "kW", "W", "GW")
ROCOF_RATIO = (0.5, 2.0)  # a ROCOF column against the frequency's derivative
MIN_QUIET = 20  # pre-event samples a ROCOF noise is estimated from


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
    derived = rocof_operator(table.time, WINDOW, breaks).apply(table.values[:, table.names.index(FREQUENCY)])
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


def rocof_component(exp) -> FilteredNoise | tuple[float, float] | None:
    """The ROCOF's noise in the bench's ``pe``, None without it. Derived from the
    frequency: the frequency recorder's noise (white + AR(1) fitted to its quiet
    pre-event samples by moments, :func:`rapid_cosim.noise.estimate.moment_noise`) through
    the ROCOF's own map (:attr:`Experiment.rocof_map`: each sample's local fit on the
    stamps as recorded), exactly (:class:`rapid_cosim.noise.timed.DerivedNoise`); from a
    ROCOF column: that column's quiet noise. Scaled by 2 H / f_nom (H fixed, or the top
    of its bounds when estimated: the noise is not underestimated). Where the frequency
    is recorded on another time base than the power, no map joins the two: the old
    approximation, a slow component (sigma, half the filter's window)."""
    if ELECTRICAL not in exp.outputs or exp.pre_step_end is None:
        return None
    table = exp.input_table
    if table is None or ROCOF not in table.names:
        return None
    given = next((s for s in exp.inputs if s.name == ROCOF and s.column), None)
    spec = given or next((s for s in exp.inputs if s.name == FREQUENCY), None)
    if spec is None:
        return None
    source = exp.source(spec)
    valid = source.valid[spec.column]
    values = spec.conversion.apply(source.time, source.columns[spec.column], valid)
    quiet = valid & (source.time < exp.pre_step_end)
    if quiet.sum() < MIN_QUIET or np.ptp(values[quiet]) == 0:
        return None
    bounds = {s.name: s.max for s in exp.estimate}
    scale = 2.0 * exp.fixed.get(INERTIA, bounds.get(INERTIA)) / exp.fixed.get("f_nom", 50.0)
    t, v = source.time[quiet], values[quiet]
    dt = source.timebase.step
    noise = moment_noise(QuietStretch(exp.name, "pre-event", t, v, trend_order=1))
    taps = (scale,) if given else tuple(scale * savgol_coeffs(points(dt), ORDER, deriv=1, delta=dt))
    if source is not exp.data:
        component = FilteredNoise(noise, taps)
        power = exp.noise_models.get(ELECTRICAL)
        return (component.sigma, WINDOW / 2) if power is not None and abs(power.dt - dt) > 0.01 * dt else component
    matrix = sparse.identity(source.time.size, format="csr") if given else exp.rocof_map.matrix
    return DerivedNoise(noise, taps, time=source.time, matrix=(scale * matrix).tocsr())


def without_unfit(exp):
    """``exp`` with the power samples whose ROCOF window held no fit left out of its fit,
    and said in its recording: their bench input is an interpolation, not a measurement."""
    rocof = exp.rocof_map
    if ELECTRICAL not in exp.outputs or rocof is None or not rocof.unfit.any():
        return exp
    spec = next(s for s in exp.inputs if s.name == FREQUENCY)
    if exp.source(spec) is not exp.data:
        return exp
    column = exp.outputs[ELECTRICAL]
    data = exp.data.with_valid({column: exp.data.valid[column] & ~rocof.unfit})
    return replace(exp, data=data, recording=replace(exp.recording, unfit=tuple(rocof.unfit_spans())))


def with_rocof_noise(exp):
    """``exp`` with the ROCOF's noise (:func:`rocof_component`) added to the noise of
    ``pe``: to its sigma, and to its noise model. The recorder's noise, estimated from
    the recorded power, does not contain it; a diagnosis's null adds it too
    (:mod:`rapid_cosim.diagnose.null`)."""
    component = rocof_component(exp)
    if component is None:
        return exp
    extra = component_sigma(component)
    sigma = exp.noise_sigma
    if sigma is not None and ELECTRICAL in sigma:
        sigma = {**sigma, ELECTRICAL: math.hypot(sigma[ELECTRICAL], extra)}
    models = dict(exp.noise_models)
    if ELECTRICAL in models:
        models[ELECTRICAL] = with_component(models[ELECTRICAL], component)
    return replace(exp, noise_sigma=sigma, noise_models=models)


def component_sigma(component: FilteredNoise | tuple[float, float]) -> float:
    """The standard deviation of a ROCOF noise component of either form."""
    return component.sigma if isinstance(component, FilteredNoise) else component[0]


def with_component(model: RecorderNoise, component: FilteredNoise | tuple[float, float]) -> RecorderNoise:
    """``model`` plus a ROCOF noise component of either form."""
    if isinstance(component, FilteredNoise):
        return replace(model, filtered=model.filtered + (component,))
    return replace(model, components=model.components + (component,))


def describe_recording(exp) -> str | None:
    """What the power column of ``exp`` was taken to be, in words for the calibration's
    output and the report (None for mechanical power): the machine constants, where the
    ROCOF comes from and, for a derived one, which PMU class its filter is like."""
    if ELECTRICAL not in exp.outputs:
        return None
    bounds = {s.name: s for s in exp.estimate}

    def constant(name: str, unit: str, default: str) -> str:
        if name in exp.fixed:
            return f"{exp.fixed[name]:g} {unit} (fixed)"
        if name in bounds:
            return f"estimated in {bounds[name].min:g} to {bounds[name].max:g} {unit}"
        return default

    clauses = [f"{exp.name}: {ELECTRICAL} is electrical power at the terminals, the governor's P_m less the "
               f"rotor's inertial and damping power", f"H {constant(INERTIA, 's', '?')}, "
               f"D {constant(DAMPING, 'pu', '0 pu (the bench default)')}"]
    column = next((s.column for s in exp.inputs if s.name == ROCOF and s.column), None)
    if column is not None:
        clauses.append(f"ROCOF from the recording's column '{column}' (checked against the frequency's derivative)")
    else:
        table = exp.input_table
        if table is None or FREQUENCY not in table.names:
            return "; ".join([*clauses, "no recorded frequency: the bench's own ROCOF"])
        spec = next(s for s in exp.inputs if s.name == FREQUENCY)
        base = exp.source(spec).timebase
        stamps = ("on regular stamps it is the Savitzky-Golay derivative" if base.regular else
                  f"fitted on the stamps as recorded ({_jitter_words(base)}), never a raw difference")
        clauses.append(f"ROCOF derived from the frequency: the slope of a local least-squares quadratic over "
                       f"{WINDOW:g} s ({points(base.step)} samples at {1.0 / base.step:.3g} per second), zero-phase, "
                       f"split at the event; {stamps}; band-limited like an IEEE C37.118.1 M-class PMU, without its "
                       "delay (not a P-class estimate)")
    component = rocof_component(exp)
    if isinstance(component, DerivedNoise):
        clauses.append(f"its noise in {ELECTRICAL}, {component_sigma(component):.2g} pu, is part of the noise model, "
                       "exactly on these stamps")
    elif component is not None:
        clauses.append(f"its noise in {ELECTRICAL}, {component_sigma(component):.2g} pu, is part of the noise model "
                       "(approximately: the frequency is recorded on another time base than the power)")
    return "; ".join(clauses)


def _jitter_words(base) -> str:
    parts = ["regular stamps" if base.jitter_max <= 0.01 * base.step else f"jitter {1e3 * base.jitter_rms:.2g} ms RMS"]
    if base.dropped:
        parts.append(f"{base.dropped} frame(s) missing")
    return ", ".join(parts)
