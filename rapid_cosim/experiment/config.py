"""Config file -> experiment: the TOML schema, and the loader that reads a spec's recordings.

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

Reading is two steps: :func:`~rapid_cosim.experiment.spec.experiment_spec` reads and
checks the sections without the measurements (:class:`~rapid_cosim.experiment.spec.ExperimentSpec`),
and :func:`experiment_from` reads, flags, masks and resamples the recordings and checks
what depends on them; :func:`parse_experiment` is both.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..data import MeasuredData, MissingColumn, describe_missing, load_measurements, noise_level
from ..data import split_hdf5_path
from ..errors import ConfigError, DataError
from ..simulator.rocof import WINDOW
from .definition import CONFIG_NAME, DEFAULT_TIMEOUT, NOISE_PRE_STEP, Experiment, SimulationSettings
from .electrical import check_rocof_column, with_rocof_noise, without_unfit
from .reader import ConfigReader, positive
from .recorder import read_noise_models
from .recording import Bridge, Recording, RecordingWarning, apply_flags, apply_limits, blanks, bridges, check_step, \
    exclude
from .signals import check_units_row
from .spec import ExperimentSpec, experiment_spec, parameter_tables
from .toml_writer import config_key

__all__ = ["load_experiment", "parse_experiment", "experiment_from", "experiment_spec", "parameter_tables",
           "config_key"]


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
    return experiment_from(experiment_spec(text, path), data, files)


def experiment_from(spec: ExperimentSpec, data: MeasuredData | None = None,
                    files: dict[str, MeasuredData] | None = None) -> Experiment:
    """The experiment a spec describes: its recordings read (unless ``data`` and ``files``
    are given), flagged, limited, resampled, windowed, their holes bridged or excluded,
    and the settings that depend on them (noise levels, the simulated span) read."""
    cfg = ConfigReader(spec.file)
    outputs, output_specs, inputs, recorded = spec.outputs, spec.output_specs, spec.inputs, spec.recorded
    given = data is not None
    if data is None:
        data = _load_data(spec.path, spec.data_file, spec.time_column, outputs, spec.file, spec.timestamp,
                          spec.event_time, time_unit=spec.time_unit, dialect=spec.dialect)
    else:
        for out, col in outputs.items():
            if col not in data.columns:
                raise ConfigError(describe_missing(col, list(data.names)), spec.file,
                                  config_key("data.outputs", out))
    check_step(data, cfg, "data.time")
    check_units_row(data.units, [*((config_key("data.outputs", o), s.column, s.conversion) for o, s in
                                   output_specs.items()),
                                 *((config_key("inputs", s.name), s.column, s.conversion) for s in inputs
                                   if s.file is None)], data.source, cfg)
    blank = blanks(data, [*outputs.values(), *(s.column for s in inputs if s.file is None)])
    with warnings.catch_warnings():
        if given:  # the recording was inspected and said when it was read: a config made from it says it once
            warnings.simplefilter("ignore", RecordingWarning)
        data, masked = apply_flags(data, recorded, cfg)
        data, more = apply_limits(data, recorded, {s.column: s.frequency for s in inputs if s.file is None and
                                                   s.frequency},
                                  {o.column: o.rating for o in output_specs.values() if o.rating})
    masked += more
    if spec.resample is not None:
        step = spec.resample
        data = data.resample(data.time[0] + step * np.arange(int((data.time[-1] - data.time[0]) / step + 1e-9) + 1))

    window = _read_window(spec.fitness, data, cfg)
    inside = _inside(data, window, outputs, spec.weights, cfg)
    pre_step_end = spec.pre_step_end
    if pre_step_end is not None and not data.time[0] < pre_step_end <= data.time[-1]:
        raise ConfigError(f"{pre_step_end:g} s is outside the record, which spans "
                          f"{data.time[0]:g} s to {data.time[-1]:g} s",
                          spec.file, "fitness.pre_step_end")
    noise_sigma = spec.noise_sigma
    if spec.noise == NOISE_PRE_STEP:  # the level of the compared, converted values
        noise_sigma = {out: sigma * output_specs[out].conversion.gain
                       for out, sigma in _pre_step_noise(outputs, data, pre_step_end, cfg).items()}
    noise_models = read_noise_models(spec.noise_tables, outputs, spec.weights, inside, cfg)
    simulation = _read_simulation(spec.simulation, inside, cfg)
    files = dict(files or {})
    for s in inputs:
        if s.file is not None and s.file not in files:
            loaded = _load_data(spec.path, s.file, s.time, {s.name: s.column}, spec.file, None, None,
                                key=config_key("inputs", s.name), dialect=spec.dialect)
            check_step(loaded, cfg, config_key("inputs", s.name))
            check_units_row(loaded.units, [(config_key("inputs", s.name), s.column, s.conversion)], loaded.source,
                            cfg)
            files[s.file], more = apply_limits(loaded, recorded, {s.column: s.frequency} if s.frequency else {}, {})
            masked += more
    bridged = check_inputs(inputs, data, files, simulation, cfg)
    left_out = [b.excluded for b in bridged if b.excluded]
    if left_out:
        data = exclude(data, list(outputs.values()), left_out)
        inside = _inside(data, window, outputs, spec.weights, cfg)
    timebases = {spec.data_file: data.timebase, **{name: d.timebase for name, d in files.items()}}

    experiment = Experiment(
        name=spec.name, config_path=spec.path, config_text=spec.text, model=spec.model,
        description=spec.description, data=data, outputs=outputs, fixed=spec.fixed, estimate=spec.estimate,
        weights=spec.weights, window=window, offset=spec.offset, noise=spec.noise, noise_sigma=noise_sigma,
        pre_step_end=pre_step_end, simulation=simulation, time_column=spec.time_column,
        conversions={o: s.conversion for o, s in output_specs.items() if not s.conversion.identity},
        inputs=inputs, files=files, noise_models=noise_models,
        recording=Recording(timebases, tuple(blank), tuple(masked), tuple(bridged),
                            notes=tuple(f"{name}: {note}" for name, d in {spec.data_file: data, **files}.items()
                                        for note in d.notes)),
    )
    check_rocof_column(experiment, cfg)
    return with_rocof_noise(without_unfit(experiment))


def check_inputs(inputs, data: MeasuredData, files: dict[str, MeasuredData], simulation,
                 cfg: ConfigReader) -> list[Bridge]:
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


def _inside(data: MeasuredData, window, outputs: dict[str, str], weights, cfg: ConfigReader) -> MeasuredData:
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


def _read_window(f: dict, data: MeasuredData, cfg: ConfigReader) -> tuple[float, float]:
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


def _pre_step_noise(outputs: dict[str, str], data: MeasuredData, pre_step_end: float,
                    cfg: ConfigReader) -> dict[str, float]:
    """Each output's noise level from its samples before ``pre_step_end`` (``noise =
    "pre-step"``), in the recording's units."""
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
    return sigma


def _read_simulation(s: dict, inside: MeasuredData, cfg: ConfigReader) -> SimulationSettings:
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
        interval = positive(cfg.number(s["output_interval"], "simulation.output_interval"),
                             cfg, "simulation.output_interval")
    else:
        dt = float(np.median(np.diff(inside.time))) if len(inside) > 1 else (stop - start) / 100
        interval = float(f"{dt / 2:.3g}")
    if interval > stop - start:
        raise ConfigError(f"output_interval {interval:g} s is longer than the simulation "
                          f"({start:g} s to {stop:g} s)", cfg.file, "simulation.output_interval")
    timeout = positive(cfg.number(s.get("timeout", DEFAULT_TIMEOUT), "simulation.timeout"),
                        cfg, "simulation.timeout")
    step = None
    if "communication_step" in s:
        step = positive(cfg.number(s["communication_step"], "simulation.communication_step"),
                         cfg, "simulation.communication_step")
    return SimulationSettings(start, stop, interval, timeout, step)


