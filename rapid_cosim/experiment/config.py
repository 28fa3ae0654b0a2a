"""Config file -> experiment: the TOML schema and its reader.

One TOML file per experiment, ``experiments/<name>/config.toml``; relative data paths are
taken from the config file's folder. :func:`load_experiment` reads one file into an
:class:`Experiment` (with its measurements loaded); :func:`rapid_cosim.fitting.problem.build_problem`
joins one or more experiments into the problem the estimators explore.

Schema (keys not shown here are rejected, with a suggestion when one is close)::

    [experiment]
    name = "test1"                          # default: the config file's folder name
    model = "iGrGen.TestBenches.StagedTest" # required: the test bench (an FMU in fmus/)
    description = "MCR 60 %, df = -200 mHz" # optional

    [data]
    file = "test1.csv"                      # required; .csv, .mat, or .h5 (run.h5:/group)
    time = "time"                           # time column, default "time"
    outputs = { pm = "pm" }                 # required: model output -> data column;
                                            # pe: electrical power (experiment.electrical)
    time_unit = "s"                         # or "ms", "us": the time column's unit
    delimiter = ";"                         # CSV: ",", ";" or "\\t" (tab); default: detected
    decimal = ","                           # CSV: "." (default) or "," (not with delimiter ",")
    flags = { column = "STAT", kind = "c37.118" }  # optional: frames marked invalid
    limits = { frequency = 5.0, power = 2.0 }      # values no recorder can mean
                                            # (experiment.recording: every key, the defaults)

    [fixed]                                 # FMU parameter values held fixed (numbers)
    documented = "unit.dyr"                 # optional: the gov.* constants of a PSS/E .dyr or
                                            # PSLF .dyd record (rapid_cosim.experiment.documented)
    "gov.p_ref" = 0.6
    "src.df" = -0.2
    "src.t_step" = 10.0

    [estimate]                              # parameters to estimate, with bounds
    "gov.R"  = { min = 0.02, max = 0.12, label = "R" }
    "gov.Ts" = { min = 0.1, max = 20.0, label = "Ts", scale = "linear", start = 5.0 }
    "meas.offset" = { min = -0.01, max = 0.01, per_experiment = true }

    [fitness]
    window = [0.0, 90.0]     # seconds; default the whole record. It may overhang the
                             # record by at most one sample interval.
    weights = { pm = 1.0 }   # per output, >= 0; default 1.0 each
    offset = true            # profile out a constant measurement offset per output
                             # (default false)
    noise = "pre-step"       # noise sigma (pu) for a Gaussian likelihood: "pre-step"
                             # (estimated from the samples before pre_step_end), a number
                             # for every output, or a table { pm = 0.0013 }. Default: none.
    pre_step_end = 10.0      # end of the quiet pre-step window; required with "pre-step"

    [noise.pm]               # the recorder's noise model of output pm (optional; see
    white = 0.00118          # rapid_cosim.experiment.recorder): the fitness is then the
    dt = 0.1                 # least squares of residuals whitened by it
    components = [{ sigma = 0.00076, tau = 0.9 }]

    [simulation]
    start_time = 0.0         # default 0.0; must not be after the first sample used
    stop_time = 90.0         # default: the last measured time inside the window
    output_interval = 0.02   # fine grid, then sampled onto the measured times;
                             # default: half the median measured sample interval
    timeout = 10.0           # wall-clock seconds per simulation, default 30
    communication_step = 0.01  # Co-Simulation FMUs only: the largest communication step
                             # (the fixed one where the FMU cannot vary it); default: the
                             # measured samples and input rows (see simulator.cosim)

Estimate entries: ``min`` and ``max`` (required numbers, ``min < max``), ``label``
(default: the name), ``scale`` (``"linear"``, or ``"log"`` for a positive range spanning
decades: the estimators then move the parameter by its logarithm),
``start`` (an initial guess inside the bounds; default the midpoint) and
``per_experiment`` (default false). Parameter names are FMU variable names; quote dotted
names (``"gov.R"``). Unquoted dotted keys (``gov.R = ...``) are read as the same name.

The measured time is taken to be the model's time: the step at ``t_step`` in the data
is at ``t_step`` in the simulation.

Joint fits: a parameter estimated in several experiments is one search dimension and
must be declared identically everywhere (same bounds, label, scale, start); a
``per_experiment`` parameter becomes one dimension per experiment, named
``"<param>@<experiment>"``.

Every mistake is a :class:`ConfigError` naming the file and the key (``estimate."gov.R".min``);
unreadable measurements stay :class:`DataError` naming the data file and row.

Over 450 lines: the schema above and the check of each section it describes are read
together, and :func:`parse_experiment` still both checks the sections and reads, flags,
masks and resamples the data; its split into a spec without I/O and a loader is not done
yet (issue 43).
"""

from __future__ import annotations

import json
import math
import re
import tomllib
import warnings
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..data import MeasuredData, MissingColumn, close_matches, describe_missing, load_measurements, noise_level
from ..data import split_hdf5_path
from ..data.csv_table import DECIMALS, DELIMITERS
from ..data.readers import TIME_UNITS
from ..errors import ConfigError, DataError
from ..simulator.rocof import WINDOW
from . import documented
from .definition import (CONFIG_NAME, DEFAULT_TIMEOUT, NOISE_PRE_STEP, SCALES, EstimateSpec, Experiment,
                         SimulationSettings)
from .electrical import check_machine, check_rocof_column, with_rocof_noise, without_unfit
from .recorder import read_noise_models
from .recording import (Bridge, Recording, RecordingWarning, apply_flags, apply_limits, blanks, bridges, check_step,
                        exclude, read_spec)
from .schema import CONFIG, ESTIMATE_ENTRY
from .signals import read_inputs, read_outputs
from .toml_writer import config_key, dotted_items

_SECTIONS: dict[str, frozenset[str] | None] = CONFIG.accepted()  # None: names the user chooses (.schema)
_REQUIRED_SECTIONS = ("experiment", "data")
_SPEC_KEYS = ESTIMATE_ENTRY.names
_NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]*$")


def load_experiment(path: str | Path) -> Experiment:
    """Read ``config.toml`` (or a folder holding one) and the data it names."""
    path = Path(path)
    if path.is_dir():
        path = path / CONFIG_NAME
    file = str(path)
    if not path.is_file():
        raise ConfigError(f"config file not found: {path.resolve()}", file)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(f"not UTF-8 text: {e}", file) from None
    return parse_experiment(text, path)


def parse_experiment(text: str, path: str | Path, data: MeasuredData | None = None,
                     files: dict[str, MeasuredData] | None = None) -> Experiment:
    """An experiment from its config text; ``path`` locates relative data files and names
    the config in errors. With ``data`` given (and ``files`` for inputs read from other
    files: a run re-built from its archive), no file is read."""
    path = Path(path)
    file = str(path)
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(_toml_message(e, text), file) from None
    if isinstance(raw.get("fixed"), dict) and documented.KEY in raw["fixed"]:  # written out: see documented
        text = documented.expand(text, raw, path)
        raw = tomllib.loads(text)
    cfg = _Reader(file)

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
    given = data is not None
    if data is None:
        data = _load_data(path, data_file, time_column, outputs, file, timestamp, event_time,
                          time_unit=_time_unit(d, cfg), dialect=dialect)
    else:
        for out, col in outputs.items():
            if col not in data.columns:
                raise ConfigError(describe_missing(col, list(data.names)), file, config_key("data.outputs", out))
    check_step(data, cfg, "data.time")
    blank = blanks(data, [*outputs.values(), *(s.column for s in inputs if s.file is None)])
    with warnings.catch_warnings():
        if given:  # the recording was inspected and said when it was read: a config made from it says it once
            warnings.simplefilter("ignore", RecordingWarning)
        data, masked = apply_flags(data, recorded, cfg)
        data, more = apply_limits(data, recorded, {s.column: s.frequency for s in inputs if s.file is None and
                                                   s.frequency},
                                  {spec.column: spec.rating for spec in output_specs.values() if spec.rating})
    masked += more
    if "resample" in d:
        if recorded.flags is not None:
            raise ConfigError("flags and resample do not go together: a STAT word cannot be interpolated; "
                              "resample the recording after masking its invalid frames", file, "data.resample")
        step = _positive(cfg.number(d["resample"], "data.resample"), cfg, "data.resample")
        data = data.resample(data.time[0] + step * np.arange(int((data.time[-1] - data.time[0]) / step + 1e-9) + 1))

    window = _read_window(f, data, cfg)
    weights = _read_weights(f, outputs, cfg)
    inside = _inside(data, window, outputs, weights, cfg)
    offset = cfg.boolean(f, "fitness", "offset", default=False)
    if pre_step_end is not None and not data.time[0] < pre_step_end <= data.time[-1]:
        raise ConfigError(f"{pre_step_end:g} s is outside the record, which spans "
                          f"{data.time[0]:g} s to {data.time[-1]:g} s",
                          file, "fitness.pre_step_end")
    noise, noise_sigma = _read_noise(f, outputs, data, pre_step_end, cfg)
    if noise_sigma is not None and noise == NOISE_PRE_STEP:  # the level of the compared, converted values
        noise_sigma = {out: sigma * output_specs[out].conversion.gain for out, sigma in noise_sigma.items()}
    noise_models = read_noise_models(sections["noise"], outputs, weights, inside, cfg)
    simulation = _read_simulation(sections["simulation"], inside, cfg)
    files = dict(files or {})
    for spec in inputs:
        if spec.file is not None and spec.file not in files:
            loaded = _load_data(path, spec.file, spec.time, {spec.name: spec.column}, file, None, None,
                                key=config_key("inputs", spec.name), dialect=dialect)
            check_step(loaded, cfg, config_key("inputs", spec.name))
            files[spec.file], more = apply_limits(loaded, recorded, {spec.column: spec.frequency}
                                                  if spec.frequency else {}, {})
            masked += more
    bridged = check_inputs(inputs, data, files, simulation, cfg)
    left_out = [b.excluded for b in bridged if b.excluded]
    if left_out:
        data = exclude(data, list(outputs.values()), left_out)
        inside = _inside(data, window, outputs, weights, cfg)
    timebases = {data_file: data.timebase, **{name: d.timebase for name, d in files.items()}}

    experiment = Experiment(
        name=name, config_path=path, config_text=text, model=model, description=description,
        data=data, outputs=outputs, fixed=fixed, estimate=estimate, weights=weights,
        window=window, offset=offset, noise=noise, noise_sigma=noise_sigma,
        pre_step_end=pre_step_end, simulation=simulation, time_column=time_column,
        conversions={o: s.conversion for o, s in output_specs.items() if not s.conversion.identity},
        inputs=inputs, files=files, noise_models=noise_models,
        recording=Recording(timebases, tuple(blank), tuple(masked), tuple(bridged),
                            notes=tuple(f"{name}: {note}" for name, d in {data_file: data, **files}.items()
                                        for note in d.notes)),
    )
    check_rocof_column(experiment, cfg)
    return with_rocof_noise(without_unfit(experiment))


def _read_model(exp: dict, path: Path, cfg: "_Reader") -> str:
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


def check_inputs(inputs, data: MeasuredData, files: dict[str, MeasuredData], simulation,
                 cfg: "_Reader") -> list[Bridge]:
    """Each input's column exists and covers the simulated span; its holes are bridged up
    to what the input allows, and longer ones refused (:mod:`.recording`)."""
    out = []
    for spec in inputs:
        key = config_key("inputs", spec.name)
        source = files[spec.file] if spec.file is not None else data
        if spec.column not in source.columns:
            raise ConfigError(describe_missing(spec.column, list(source.names)), cfg.file, f"{key}.column")
        out += bridges(spec.name, spec.column, source, simulation.start_time, simulation.stop_time, spec.gaps, cfg,
                       WINDOW)
    return out


def _inside(data: MeasuredData, window, outputs: dict[str, str], weights, cfg: "_Reader") -> MeasuredData:
    """The samples inside the fitness window; each output of weight has some valid."""
    try:
        inside = data.window(*window)
    except DataError as e:
        raise ConfigError(e.detail, cfg.file, "fitness.window") from None
    for out, col in outputs.items():
        if weights[out] > 0 and inside.n_valid(col) == 0:
            raise ConfigError(f"no valid samples of column '{col}' (output {out}) in the "
                              f"window {list(window)} s", cfg.file, "fitness.window")
    return inside


def _time_unit(d: dict, cfg: "_Reader") -> str:
    unit = cfg.string(d, "data", "time_unit", default="s")
    if unit not in TIME_UNITS:
        raise ConfigError(f"time_unit {unit!r} is not one of {', '.join(TIME_UNITS)}", cfg.file, "data.time_unit")
    return unit


def _dialect(d: dict, cfg: "_Reader") -> tuple[str | None, str]:
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


def _load_data(config: Path, data_file: str, time_column: str, outputs: dict[str, str],
               file: str, timestamp: str | None, event_time, key: str | None = None,
               time_unit: str = "s", dialect: tuple[str | None, str] = (None, ".")) -> MeasuredData:
    fpath, group = split_hdf5_path(data_file)
    if not fpath.is_absolute():
        fpath = config.parent / fpath
    if not fpath.is_file():
        raise ConfigError(f"data file not found: {fpath.resolve()}", file, key or "data.file")
    target = str(fpath) + (f":{group}" if group != "/" else "")
    try:
        data = load_measurements(target, time_column=time_column, timestamp=timestamp, event_time=event_time,
                                 time_unit=time_unit, delimiter=dialect[0], decimal=dialect[1])
    except MissingColumn as e:  # only the time column can be missing here
        raise ConfigError(f"{target}: {e.detail}", file, key or ("data.timestamp" if timestamp else "data.time")) \
            from None
    for out, col in outputs.items():
        if col not in data.columns:
            raise ConfigError(f"{target}: {describe_missing(col, list(data.names))}",
                              file, key or config_key("data.outputs", out))
    return data


def _read_fixed(table: dict, cfg: "_Reader") -> dict[str, float]:
    fixed: dict[str, float] = {}
    for name, value in dotted_items(table, lambda v: not isinstance(v, dict)):
        key = config_key("fixed", name)
        cfg.parameter_name(name, key)
        if name in fixed:
            raise ConfigError(f"'{name}' is given twice (quoted and as dotted keys)", cfg.file, key)
        fixed[name] = cfg.number(value, key)
    return fixed


def _read_estimate(table: dict, cfg: "_Reader", section: str = "estimate") -> tuple[EstimateSpec, ...]:
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
    cfg = _Reader(file)
    values = _read_fixed({k: v for k, v in fixed.items() if k != documented.KEY}, cfg)
    return values, {s.name: s for s in _read_estimate(estimate, cfg, section)}


def _read_window(f: dict, data: MeasuredData, cfg: "_Reader") -> tuple[float, float]:
    t_first, t_last = float(data.time[0]), float(data.time[-1])
    if "window" not in f:
        return t_first, t_last
    w = f["window"]
    if not isinstance(w, list) or len(w) != 2:
        raise ConfigError(f"expected [start, end] in seconds, got {w!r}", cfg.file, "fitness.window")
    t0 = cfg.number(w[0], "fitness.window")
    t1 = cfg.number(w[1], "fitness.window")
    if not t0 < t1:
        raise ConfigError(f"start ({t0:g} s) must be before end ({t1:g} s)", cfg.file, "fitness.window")
    dt = float(np.median(np.diff(data.time))) if len(data) > 1 else 0.0
    if t0 < t_first - dt or t1 > t_last + dt:
        raise ConfigError(f"window [{t0:g}, {t1:g}] s reaches outside the data, which spans "
                          f"{t_first:g} s to {t_last:g} s", cfg.file, "fitness.window")
    return t0, t1


def _read_weights(f: dict, outputs: dict[str, str], cfg: "_Reader") -> dict[str, float]:
    weights = {out: 1.0 for out in outputs}
    if "weights" in f:
        table = cfg.table(f["weights"], "fitness.weights")
        for out, w in table.items():
            key = config_key("fitness.weights", out)
            if out not in outputs:
                raise ConfigError(f"'{out}' is not an output{_suggest(out, list(outputs))}; "
                                  f"outputs: {', '.join(outputs)}", cfg.file, key)
            w = cfg.number(w, key)
            if w < 0:
                raise ConfigError(f"weight {w:g} is negative", cfg.file, key)
            weights[out] = w
        if not any(w > 0 for w in weights.values()):
            raise ConfigError("at least one weight must be positive", cfg.file, "fitness.weights")
    return weights


def _read_noise(f: dict, outputs: dict[str, str], data: MeasuredData, pre_step_end: float | None,
                cfg: "_Reader") -> tuple[Any, dict[str, float] | None]:
    if "noise" not in f:
        return None, None
    noise = f["noise"]
    if isinstance(noise, str):
        if noise != NOISE_PRE_STEP:
            raise ConfigError(f"expected \"{NOISE_PRE_STEP}\", a number or a table per output, "
                              f"got {noise!r}{_suggest(noise, [NOISE_PRE_STEP])}",
                              cfg.file, "fitness.noise")
        if pre_step_end is None:
            raise ConfigError(f"noise = \"{NOISE_PRE_STEP}\" needs pre_step_end (the end of the "
                              f"quiet samples before the step)", cfg.file, "fitness.pre_step_end")
        sigma = {}
        for out, col in outputs.items():
            try:
                sigma[out] = noise_level(data, col, pre_step_end).sigma
            except DataError as e:
                raise ConfigError(e.detail, cfg.file, "fitness.pre_step_end") from None
            if not sigma[out] > 0:
                raise ConfigError(f"column '{col}' is constant before {pre_step_end:g} s, so its "
                                  f"noise level is zero; give noise as a number",
                                  cfg.file, "fitness.noise")
        return noise, sigma
    if isinstance(noise, dict):
        sigma = {}
        for out, v in noise.items():
            key = config_key("fitness.noise", out)
            if out not in outputs:
                raise ConfigError(f"'{out}' is not an output{_suggest(out, list(outputs))}",
                                  cfg.file, key)
            sigma[out] = _positive(cfg.number(v, key), cfg, key)
        missing = [o for o in outputs if o not in sigma]
        if missing:
            raise ConfigError(f"no noise level for output(s) {', '.join(missing)}",
                              cfg.file, "fitness.noise")
        return dict(noise), sigma
    value = _positive(cfg.number(noise, "fitness.noise"), cfg, "fitness.noise")
    return value, {out: value for out in outputs}


def _read_simulation(s: dict, inside: MeasuredData, cfg: "_Reader") -> SimulationSettings:
    first, last = float(inside.time[0]), float(inside.time[-1])
    start = cfg.number(s.get("start_time", 0.0), "simulation.start_time")
    if start > first:
        raise ConfigError(f"start_time {start:g} s is after the first sample used "
                          f"({first:g} s)", cfg.file, "simulation.start_time")
    stop = cfg.number(s.get("stop_time", last), "simulation.stop_time")
    if stop < last:
        raise ConfigError(f"stop_time {stop:g} s ends before the last sample used ({last:g} s); "
                          f"shorten fitness.window or simulate longer", cfg.file, "simulation.stop_time")
    if "output_interval" in s:
        interval = _positive(cfg.number(s["output_interval"], "simulation.output_interval"),
                             cfg, "simulation.output_interval")
    else:
        dt = float(np.median(np.diff(inside.time))) if len(inside) > 1 else (stop - start) / 100
        interval = float(f"{dt / 2:.3g}")
    if interval > stop - start:
        raise ConfigError(f"output_interval {interval:g} s is longer than the simulation "
                          f"({start:g} s to {stop:g} s)", cfg.file, "simulation.output_interval")
    timeout = _positive(cfg.number(s.get("timeout", DEFAULT_TIMEOUT), "simulation.timeout"),
                        cfg, "simulation.timeout")
    step = None
    if "communication_step" in s:
        step = _positive(cfg.number(s["communication_step"], "simulation.communication_step"),
                         cfg, "simulation.communication_step")
    return SimulationSettings(start, stop, interval, timeout, step)


class _Reader:
    """Typed access to parsed TOML that raises ConfigError naming file and key."""

    def __init__(self, file: str):
        self.file = file

    def check_keys(self, table: dict, known: frozenset[str], where: str) -> None:
        for k in table:
            if k not in known:
                what = f"top-level key '{k}'" if not where else f"key '{k}'"
                raise ConfigError(f"unknown {what}{_suggest(k, sorted(known))}; allowed: "
                                  f"{', '.join(sorted(known))}", self.file, config_key(where, k))

    def table(self, value, key: str) -> dict:
        if not isinstance(value, dict):
            raise ConfigError(f"expected a table, got {value!r}", self.file, key)
        return value

    def require(self, table: dict, where: str, k: str):
        if k not in table:
            raise ConfigError(f"missing required key '{k}'", self.file, config_key(where, k))
        return table[k]

    def string(self, table: dict, where: str, k: str, default: str | None = None,
               allow_empty: bool = False) -> str:
        value = self.require(table, where, k) if default is None else table.get(k, default)
        if not isinstance(value, str) or not (value.strip() or allow_empty):
            raise ConfigError(f"expected a non-empty string, got {value!r}", self.file, config_key(where, k))
        return value

    def boolean(self, table: dict, where: str, k: str, default: bool) -> bool:
        value = table.get(k, default)
        if not isinstance(value, bool):
            raise ConfigError(f"expected true or false, got {value!r}", self.file, config_key(where, k))
        return value

    def number(self, value, key: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"expected a number, got {value!r}", self.file, key)
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f"expected a finite number, got {value}", self.file, key)
        return value

    def parameter_name(self, name: str, key: str) -> None:
        if "@" in name or not name.strip():
            raise ConfigError(f"'{name}' is not a parameter name ('@' is reserved for "
                              f"per-experiment dimensions)", self.file, key)


def _positive(value: float, cfg: _Reader, key: str) -> float:
    if not value > 0:
        raise ConfigError(f"must be positive, got {value:g}", cfg.file, key)
    return value


def _suggest(word: str, candidates: Sequence[str]) -> str:
    close = close_matches(word, list(candidates))
    return f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""


def _toml_message(e: tomllib.TOMLDecodeError, text: str) -> str:
    message = f"invalid TOML: {e}"
    m = re.search(r"at line (\d+)", str(e))
    if m:
        lines = text.splitlines()
        n = int(m.group(1))
        if 1 <= n <= len(lines):
            message += f"\n    {n} | {lines[n - 1]}"
    return message


