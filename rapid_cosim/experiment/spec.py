"""A config's text -> :class:`ExperimentSpec`: every section the schema of :mod:`.config`
describes, read and checked without reading the measurements. What can only be checked
against the data (the window, the noise level before the step, the simulated span, the
inputs' coverage) is the loader's (:func:`rapid_cosim.experiment.config.experiment_from`).
The one file read here is a ``documented`` record in ``[fixed]``, which is part of the
config as an include is. Since every section is checked here, before any recording is
read, a config with several mistakes is told of the section's first (``[data]``'s
resample and time unit, ``[fitness]``'s weights, offset and noise) before a missing or
unreadable data file, where versions before the split named the file first."""

from __future__ import annotations

import json
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..data.csv_table import DECIMALS, DELIMITERS
from ..data.readers import TIME_UNITS
from ..errors import ConfigError
from . import documented
from .definition import NOISE_PRE_STEP, SCALES, EstimateSpec
from .electrical import check_machine
from .reader import ConfigReader, positive, suggest, toml_message
from .recording import RecordingSpec, read_spec
from .schema import CONFIG, ESTIMATE_ENTRY
from .signals import InputSpec, OutputSpec, read_inputs, read_outputs
from .toml_writer import config_key, dotted_items

_SECTIONS: dict[str, frozenset[str] | None] = CONFIG.accepted()  # None: names the user chooses (.schema)
_REQUIRED_SECTIONS = ("experiment", "data")
_SPEC_KEYS = ESTIMATE_ENTRY.names
_NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]*$")


@dataclass(frozen=True, eq=False)
class ExperimentSpec:
    """A config as its schema reads it: names, files and settings, no measurement."""

    path: Path
    text: str  # the config's text, a documented record written out
    name: str
    model: str
    description: str
    data_file: str
    timestamp: str | None
    time_column: str
    event_time: Any
    time_unit: str
    dialect: tuple[str | None, str]  # the CSV delimiter (None: detected), the decimal separator
    recorded: RecordingSpec
    resample: float | None
    output_specs: dict[str, OutputSpec]
    fixed: dict[str, float]
    estimate: tuple[EstimateSpec, ...]
    weights: dict[str, float]
    offset: bool
    pre_step_end: float | None
    noise: Any  # as given: None, "pre-step", a number or a table per output
    noise_sigma: dict[str, float] | None  # the levels given (None: none, or read from the data)
    inputs: tuple[InputSpec, ...]
    fitness: dict  # [fitness] as written, for the window the data check
    noise_tables: dict  # [noise], the recorder's models, checked against the data's span
    simulation: dict  # [simulation] as written, its defaults the data's

    @property
    def file(self) -> str:
        return str(self.path)

    @property
    def outputs(self) -> dict[str, str]:
        """Model output -> data column."""
        return {out: spec.column for out, spec in self.output_specs.items()}


def experiment_spec(text: str, path: str | Path) -> ExperimentSpec:
    """The spec of a config's ``text``; ``path`` names it in errors and locates what it
    names relative to its folder."""
    path = Path(path)
    file = str(path)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(toml_message(e, text), file) from None
    if isinstance(raw.get("fixed"), dict) and documented.KEY in raw["fixed"]:  # written out: see documented
        text = documented.expand(text, raw, path)
        raw = tomllib.loads(text)
    cfg = ConfigReader(file)

    cfg.check_keys(raw, frozenset(_SECTIONS), "")
    for section in _REQUIRED_SECTIONS:
        if section not in raw:
            raise ConfigError(f"missing section [{section}]", file, section)
    sections = {s: cfg.table(raw.get(s, {}), s) for s in _SECTIONS}
    for s, known in _SECTIONS.items():
        if known is not None:
            cfg.check_keys(sections[s], known, s)

    exp = sections["experiment"]
    name = cfg.string(exp, "experiment", "name", default=path.resolve().parent.name)
    if not _NAME_RE.match(name):
        raise ConfigError(f"name {name!r} must be letters, digits, '_', '-' or '.' "
                          f"(it names search dimensions <param>@<name> and archive groups)",
                          file, "experiment.name")
    model = _read_model(exp, path, cfg)
    description = cfg.string(exp, "experiment", "description", default="", allow_empty=True)

    d = sections["data"]
    data_file = cfg.string(d, "data", "file")
    timestamp = cfg.string(d, "data", "timestamp") if "timestamp" in d else None
    time_column = timestamp or cfg.string(d, "data", "time", default="time")
    event_time = d.get("event_time")
    if event_time is not None and (timestamp is None or isinstance(event_time, bool)
                                   or not isinstance(event_time, (str, int, float))):
        raise ConfigError("event_time (a timestamp, or epoch seconds) goes with a timestamp column",
                          file, "data.event_time")
    out_table = cfg.table(cfg.require(d, "data", "outputs"), "data.outputs")
    if not out_table:
        raise ConfigError("needs at least one model output -> data column", file, "data.outputs")
    output_specs = read_outputs(out_table, cfg)
    outputs = {out: spec.column for out, spec in output_specs.items()}

    fixed = _read_fixed(sections["fixed"], cfg)
    estimate = _read_estimate(sections["estimate"], cfg)
    both = sorted(set(fixed) & {s.name for s in estimate})
    if both:
        raise ConfigError(f"{', '.join(both)} is both fixed and estimated; keep one",
                          file, config_key("estimate", both[0]))
    check_machine(outputs, fixed, estimate, cfg)

    f = sections["fitness"]
    pre_step_end = cfg.number(f["pre_step_end"], "fitness.pre_step_end") if "pre_step_end" in f else None
    inputs = read_inputs(sections["inputs"], cfg, pre_step_end)
    recorded = read_spec(d, cfg)
    dialect = _dialect(d, cfg)
    time_unit = _time_unit(d, cfg)
    resample = None
    if "resample" in d:
        if recorded.flags is not None:
            raise ConfigError("flags and resample do not go together: a STAT word cannot be interpolated; "
                              "resample the recording after masking its invalid frames", file, "data.resample")
        resample = positive(cfg.number(d["resample"], "data.resample"), cfg, "data.resample")
    weights = _read_weights(f, outputs, cfg)
    offset = cfg.boolean(f, "fitness", "offset", default=False)
    noise, noise_sigma = _read_noise(f, outputs, pre_step_end, cfg)
    return ExperimentSpec(path, text, name, model, description, data_file, timestamp, time_column, event_time,
                          time_unit, dialect, recorded, resample, output_specs, fixed, estimate, weights, offset,
                          pre_step_end, noise, noise_sigma, inputs, f, sections["noise"], sections["simulation"])


def _read_noise(f: dict, outputs: dict[str, str], pre_step_end: float | None,
                cfg: ConfigReader) -> tuple[Any, dict[str, float] | None]:
    """``[fitness] noise`` as given, and the levels it gives (none for "pre-step", whose
    levels the loader reads from the samples before the step)."""
    if "noise" not in f:
        return None, None
    noise = f["noise"]
    if isinstance(noise, str):
        if noise != NOISE_PRE_STEP:
            raise ConfigError(f"expected \"{NOISE_PRE_STEP}\", a number or a table per output, "
                              f"got {noise!r}{suggest(noise, [NOISE_PRE_STEP])}",
                              cfg.file, "fitness.noise")
        if pre_step_end is None:
            raise ConfigError(f"noise = \"{NOISE_PRE_STEP}\" needs pre_step_end (the end of the "
                              f"quiet samples before the step)", cfg.file, "fitness.pre_step_end")
        return noise, None
    if isinstance(noise, dict):
        sigma = {}
        for out, v in noise.items():
            key = config_key("fitness.noise", out)
            if out not in outputs:
                raise ConfigError(f"'{out}' is not an output{suggest(out, list(outputs))}",
                                  cfg.file, key)
            sigma[out] = positive(cfg.number(v, key), cfg, key)
        missing = [o for o in outputs if o not in sigma]
        if missing:
            raise ConfigError(f"no noise level for output(s) {', '.join(missing)}",
                              cfg.file, "fitness.noise")
        return dict(noise), sigma
    value = positive(cfg.number(noise, "fitness.noise"), cfg, "fitness.noise")
    return value, {out: value for out in outputs}


def _read_model(exp: dict, path: Path, cfg: ConfigReader) -> str:
    """A bench of the package (``model``), or any FMU file (``fmu``, or a ``model`` ending
    in .fmu), made absolute from the config's folder."""
    if ("model" in exp) == ("fmu" in exp):
        raise ConfigError("give either model (a class of the package) or fmu (an FMU file), not both or neither",
                          cfg.file, "experiment.model")
    key = "fmu" if "fmu" in exp else "model"
    value = cfg.string(exp, "experiment", key)
    if key == "model" and not value.endswith(".fmu"):
        return value
    if not value.endswith(".fmu"):
        raise ConfigError(f"{value!r} is not an .fmu file", cfg.file, f"experiment.{key}")
    fmu = Path(value)
    return str(fmu if fmu.is_absolute() else (path.parent / fmu).resolve())


def _time_unit(d: dict, cfg: ConfigReader) -> str:
    unit = cfg.string(d, "data", "time_unit", default="s")
    if unit not in TIME_UNITS:
        raise ConfigError(f"time_unit {unit!r} is not one of {', '.join(TIME_UNITS)}", cfg.file, "data.time_unit")
    return unit


def _dialect(d: dict, cfg: ConfigReader) -> tuple[str | None, str]:
    """How the experiment's CSV files are written: the delimiter (None: detected) and
    the decimal separator."""
    delimiter = None
    if "delimiter" in d:
        delimiter = cfg.string(d, "data", "delimiter", allow_empty=True)  # a tab is blank
        if delimiter not in DELIMITERS:
            raise ConfigError(f"delimiter {_quoted(delimiter)} is not one of {', '.join(map(_quoted, DELIMITERS))}; "
                              "leave it out to detect it", cfg.file, "data.delimiter")
    decimal = cfg.string(d, "data", "decimal", default=".")
    if decimal not in DECIMALS:
        raise ConfigError(f"decimal {_quoted(decimal)} is not one of {', '.join(map(_quoted, DECIMALS))}",
                          cfg.file, "data.decimal")
    if decimal == "," == delimiter:
        raise ConfigError('decimal = "," needs a delimiter other than "," (one comma cannot separate both fields '
                          'and decimals): set delimiter = ";" or "\\t", or leave it out to detect it',
                          cfg.file, "data.decimal")
    return delimiter, decimal


def _quoted(text: str) -> str:
    return json.dumps(text)  # as TOML writes it: "\t" for a tab


def _read_fixed(table: dict, cfg: ConfigReader) -> dict[str, float]:
    fixed: dict[str, float] = {}
    for name, value in dotted_items(table, lambda v: not isinstance(v, dict)):
        key = config_key("fixed", name)
        cfg.parameter_name(name, key)
        if name in fixed:
            raise ConfigError(f"'{name}' is given twice (quoted and as dotted keys)", cfg.file, key)
        fixed[name] = cfg.number(value, key)
    return fixed


def _read_estimate(table: dict, cfg: ConfigReader, section: str = "estimate") -> tuple[EstimateSpec, ...]:
    def is_spec(v):
        return (not isinstance(v, dict) or not v or bool(_SPEC_KEYS & v.keys())
                or any(not isinstance(x, dict) for x in v.values()))

    specs: dict[str, EstimateSpec] = {}
    for name, value in dotted_items(table, is_spec):
        key = config_key(section, name)
        cfg.parameter_name(name, key)
        if name in specs:
            raise ConfigError(f"'{name}' is given twice (quoted and as dotted keys)", cfg.file, key)
        if not isinstance(value, dict):
            raise ConfigError(f"expected a table such as {{ min = 0.02, max = 0.12 }}, "
                              f"got {value!r}", cfg.file, key)
        cfg.check_keys(value, _SPEC_KEYS, key)
        lo = cfg.number(cfg.require(value, key, "min"), f"{key}.min")
        hi = cfg.number(cfg.require(value, key, "max"), f"{key}.max")
        if not lo < hi:
            raise ConfigError(f"min ({lo:g}) must be less than max ({hi:g})", cfg.file, key)
        scale = cfg.string(value, key, "scale", default="linear")
        if scale not in SCALES:
            raise ConfigError(f"scale {scale!r} is not supported; use one of {', '.join(SCALES)}",
                              cfg.file, f"{key}.scale")
        if scale == "log" and not lo > 0:
            raise ConfigError(f"scale \"log\" needs min > 0, got {lo:g}", cfg.file, f"{key}.min")
        start = None
        if "start" in value:
            start = cfg.number(value["start"], f"{key}.start")
            if not lo <= start <= hi:
                raise ConfigError(f"start {start:g} is outside [{lo:g}, {hi:g}]",
                                  cfg.file, f"{key}.start")
        specs[name] = EstimateSpec(
            name=name, min=lo, max=hi, label=cfg.string(value, key, "label", default=name),
            per_experiment=cfg.boolean(value, key, "per_experiment", default=False),
            scale=scale, start=start)
    return tuple(specs.values())


def parameter_tables(fixed: dict, estimate: dict, file: str,
                     section: str = "estimate") -> tuple[dict[str, float], dict[str, EstimateSpec]]:
    """A structure file's ``[fixed]`` and ``[estimate]`` (or ``[optional]``) read and
    checked as a config's are, dotted keys flattened, every error naming ``file`` and its
    key: the tables become the tests' configs, and an error named by a test's config
    sends the user to the wrong file."""
    cfg = ConfigReader(file)
    values = _read_fixed({k: v for k, v in fixed.items() if k != documented.KEY}, cfg)
    return values, {s.name: s for s in _read_estimate(estimate, cfg, section)}


def _read_weights(f: dict, outputs: dict[str, str], cfg: ConfigReader) -> dict[str, float]:
    weights = {out: 1.0 for out in outputs}
    if "weights" in f:
        table = cfg.table(f["weights"], "fitness.weights")
        for out, w in table.items():
            key = config_key("fitness.weights", out)
            if out not in outputs:
                raise ConfigError(f"'{out}' is not an output{suggest(out, list(outputs))}; "
                                  f"outputs: {', '.join(outputs)}", cfg.file, key)
            w = cfg.number(w, key)
            if w < 0:
                raise ConfigError(f"weight {w:g} is negative", cfg.file, key)
            weights[out] = w
        if not any(w > 0 for w in weights.values()):
            raise ConfigError("at least one weight must be positive", cfg.file, "fitness.weights")
    return weights
