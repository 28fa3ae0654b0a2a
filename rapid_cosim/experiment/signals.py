"""Measured signals <-> model variables: what drives a model's inputs, and what its
outputs are compared with, with units and conversions.

A ``[inputs]`` entry maps one model input to a data column::

    [inputs]
    f_dev = { column = "FREQ", unit = "Hz", convert = "deviation", nominal = 50.0,
              baseline = "pre-event" }
    dw = { column = "f", file = "pmu.csv", time = "t", convert = "deviation_pu", nominal = 50.0,
           sign = -1 }

and an output may be converted the same way (``outputs = { pm = { column = "P_MW",
scale = 0.0025 } }``: MW on a 400 MW base; or ``rating = 400.0``, MVA, the same; a power in
MW without either is an error). ``pe`` is electrical power at the terminals
(:mod:`.electrical`); a ``rocof`` input (``unit = "Hz/s"`` or ``"mHz/s"``) is checked
against the frequency's derivative, and derived from it when not given. The value given to the model is::

    sign * scale * converted(column * unit factor) + offset     (minus a baseline)

with ``convert`` one of ``"none"`` (the value itself), ``"deviation"`` (value minus
``nominal``, given in the unit's base: Hz for a column in mHz) and ``"deviation_pu"``
(``(value - nominal) / nominal``); ``unit``
scales the column to its dimension's base (``mHz`` to ``Hz``, ``kW`` to ``MW``); and
``baseline`` removes the mean (``"pre-event"``) or a straight line (``"detrend"``) of the
samples before ``baseline_end`` (default: ``[fitness] pre_step_end``), so that a
recorder's steady offset is not taken for a disturbance. An input may come from another
file than the outputs (``file``, with its own ``time`` column, on the same time base).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from ..errors import ConfigError
from .electrical import POWER_UNITS, check_rating
from .recording import FREQUENCY_UNITS, SHORT_GAP, read_gaps
from .schema import INPUT, OUTPUT
from .toml_writer import config_key

UNITS = {"": 1.0, "1": 1.0, "pu": 1.0, "Hz": 1.0, "mHz": 1e-3, "kHz": 1e3, "MW": 1.0, "kW": 1e-3, "W": 1e-6,
         "GW": 1e3, "Mvar": 1.0, "s": 1.0, "rad/s": 1.0, "Hz/s": 1.0, "mHz/s": 1e-3}
CONVERSIONS = ("none", "deviation", "deviation_pu")
BASELINES = ("none", "pre-event", "detrend")
INPUT_KEYS = INPUT.names
OUTPUT_KEYS = OUTPUT.names


_DIMENSIONS = ({"Hz", "mHz", "kHz"}, {"MW", "kW", "W", "GW"}, {"Hz/s", "mHz/s"})


def check_units_row(units: Mapping[str, str], columns: Sequence[tuple[str, str, "Conversion"]], source: str,
                    cfg) -> None:
    """A column whose units row states another unit of its dimension than the config reads
    it in is refused, naming both: read as stated, a frequency in mHz taken as Hz lies a
    thousand times off and every sample falls outside the plausible band. ``columns``:
    (the config key, the column, its conversion) of each column the config reads."""
    for key, column, conversion in columns:
        stated = units.get(column, "").strip("[]() ")
        if stated not in UNITS or stated == conversion.unit:
            continue
        given = conversion.unit
        same = any(stated in d and given in d for d in _DIMENSIONS)
        if same or (not given and UNITS[stated] != 1.0):
            read = f"'{given}'" if given else "its own units (no unit given)"
            raise ConfigError(f"the units row of {source} gives column '{column}' in '{stated}', but the config "
                              f"reads it in {read}: set unit = \"{stated}\" (values are scaled to the dimension's "
                              f"base), or correct the units row", cfg.file, f"{key}.unit")


@dataclass(frozen=True)
class Conversion:
    unit: str = ""
    convert: str = "none"
    nominal: float | None = None
    scale: float = 1.0
    offset: float = 0.0
    sign: float = 1.0
    baseline: str = "none"
    baseline_end: float | None = None

    @property
    def identity(self) -> bool:
        return self == Conversion(unit=self.unit) and UNITS[self.unit] == 1.0

    @property
    def gain(self) -> float:
        """How much a small change of the column changes the value (a noise level's factor)."""
        return abs(UNITS[self.unit] * self.scale / (self.nominal if self.convert == "deviation_pu" else 1.0))

    def apply(self, time: np.ndarray, values: np.ndarray, valid: np.ndarray) -> np.ndarray:
        v = np.asarray(values, dtype=float) * UNITS[self.unit]
        if self.convert == "deviation":
            v = v - self.nominal
        elif self.convert == "deviation_pu":
            v = (v - self.nominal) / self.nominal
        v = self.sign * self.scale * v + self.offset
        if self.baseline != "none":
            before = valid & (time < self.baseline_end)
            if self.baseline == "pre-event":
                v = v - np.mean(v[before])
            else:
                slope, intercept = np.polyfit(time[before], v[before], 1)
                v = v - (slope * time + intercept)
        return v


@dataclass(frozen=True)
class InputSpec:
    """One model input and the measured column that drives it."""

    name: str
    column: str
    file: str | None = None  # another data file than [data] file, on the same time base
    time: str = "time"  # that file's time column
    conversion: Conversion = Conversion()
    gaps: float = SHORT_GAP  # the longest hole bridged by interpolation (s): .recording

    @property
    def frequency(self) -> tuple[float, float] | None:
        """(the column's factor to Hz, the nominal in Hz) when it records a grid frequency
        (converted about a nominal of 40 to 70 Hz), else None: what its limits check."""
        c = self.conversion
        if c.convert == "none" or c.nominal is None or c.unit not in FREQUENCY_UNITS:
            return None
        nominal = c.nominal  # in the unit's base, Hz, as the conversion subtracts it
        return (FREQUENCY_UNITS[c.unit], nominal) if 40.0 <= nominal <= 70.0 else None


@dataclass(frozen=True)
class OutputSpec:
    """One model output and the measured column it is compared with."""

    name: str
    column: str
    conversion: Conversion = Conversion()

    @property
    def rating(self) -> float | None:
        """The unit's rating in the column's own unit, for a power on a rating (else None)."""
        c = self.conversion
        if c.unit not in POWER_UNITS or c.convert != "none" or not c.scale:
            return None
        return abs(1.0 / (c.scale * UNITS[c.unit]))


# --------------------------------------------------------------------------- reading


def read_outputs(table: dict, cfg) -> dict[str, OutputSpec]:
    """``[data] outputs``: output -> column, or output -> a table with ``column`` and a
    conversion."""
    out = {}
    for name, value in table.items():
        key = config_key("data.outputs", name)
        if isinstance(value, str):
            out[name] = OutputSpec(name, cfg.string({name: value}, "data.outputs", name))
            continue
        spec = cfg.table(value, key)
        cfg.check_keys(spec, OUTPUT_KEYS, key)
        scale = check_rating(spec, cfg, key)  # MW on the unit's rating; MW without one is an error
        conversion = _conversion(spec, cfg, key, None)
        out[name] = OutputSpec(name, cfg.string(spec, key, "column"),
                               conversion if scale is None else replace(conversion, scale=scale))
    return out


def read_inputs(table: dict, cfg, pre_step_end: float | None) -> tuple[InputSpec, ...]:
    specs = []
    for name, value in table.items():
        key = config_key("inputs", name)
        spec = cfg.table(value, key)
        cfg.check_keys(spec, INPUT_KEYS, key)
        file = cfg.string(spec, key, "file") if "file" in spec else None
        specs.append(InputSpec(name, cfg.string(spec, key, "column"), file,
                               cfg.string(spec, key, "time", default="time"),
                               _conversion(spec, cfg, key, pre_step_end), read_gaps(spec, cfg, key)))
    return tuple(specs)


def _conversion(spec: dict, cfg, key: str, pre_step_end: float | None) -> Conversion:
    unit = spec.get("unit", "")
    if not isinstance(unit, str) or unit not in UNITS:
        raise ConfigError(f"unit {unit!r} is not known; units: {', '.join(u for u in UNITS if u)}", cfg.file,
                          f"{key}.unit")
    convert = cfg.string(spec, key, "convert", default="none")
    if convert not in CONVERSIONS:
        raise ConfigError(f"convert {convert!r} is not one of {', '.join(CONVERSIONS)}", cfg.file, f"{key}.convert")
    nominal = cfg.number(spec["nominal"], f"{key}.nominal") if "nominal" in spec else None
    if convert != "none" and nominal is None:
        raise ConfigError(f"convert = \"{convert}\" needs the nominal value (nominal = 50.0)", cfg.file, key)
    if convert == "deviation_pu" and not nominal:
        raise ConfigError("a per-unit deviation needs a nonzero nominal value", cfg.file, f"{key}.nominal")
    sign = cfg.number(spec.get("sign", 1.0), f"{key}.sign")
    if sign not in (1.0, -1.0):
        raise ConfigError(f"sign must be 1 or -1, got {sign:g}", cfg.file, f"{key}.sign")
    baseline = cfg.string(spec, key, "baseline", default="none")
    if baseline not in BASELINES:
        raise ConfigError(f"baseline {baseline!r} is not one of {', '.join(BASELINES)}", cfg.file,
                          f"{key}.baseline")
    end = cfg.number(spec["baseline_end"], f"{key}.baseline_end") if "baseline_end" in spec else pre_step_end
    if baseline != "none" and end is None:
        raise ConfigError(f"baseline = \"{baseline}\" needs the end of the quiet samples (baseline_end, or "
                          "[fitness] pre_step_end)", cfg.file, key)
    return Conversion(unit, convert, nominal, cfg.number(spec.get("scale", 1.0), f"{key}.scale"),
                      cfg.number(spec.get("offset", 0.0), f"{key}.offset"), sign, baseline, end)
