"""An experiment: one test's measurements, its model and what is estimated from it.

An :class:`Experiment` is made from a TOML config file
(:func:`~rapid_cosim.experiment.config.load_experiment`) or in code from arrays or a
pandas DataFrame (:mod:`rapid_cosim.experiment.construct`). Either way it carries the
text of its config, so that an archive can keep it and re-run it alone. The makers live
with the loader; this module, the dataclasses, imports neither.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data import MeasuredData
from ..noise import RecorderNoise
from ..simulator import InputTable
from ..simulator.rocof import FREQUENCY, ROCOF, WINDOW, RocofOperator, rocof_operator
from .recording import Recording
from .signals import Conversion, InputSpec

CONFIG_NAME = "config.toml"
DEFAULT_TIMEOUT = 30.0
SCALES = ("linear", "log")
NOISE_PRE_STEP = "pre-step"
IN_MEMORY = "(in memory)"  # the data file of an experiment made in code


@dataclass(frozen=True)
class EstimateSpec:
    """One ``[estimate]`` entry."""

    name: str
    min: float
    max: float
    label: str
    per_experiment: bool = False
    scale: str = "linear"
    start: float | None = None

    def to_config(self) -> dict:
        """This entry as a config's ``[estimate]`` table writes it, defaults left out, so
        that a config rendered from it reads back as this entry."""
        out: dict = {"min": self.min, "max": self.max}
        if self.label != self.name:
            out["label"] = self.label
        if self.per_experiment:
            out["per_experiment"] = True
        if self.scale != "linear":
            out["scale"] = self.scale
        if self.start is not None:
            out["start"] = self.start
        return out


@dataclass(frozen=True)
class SimulationSettings:
    start_time: float
    stop_time: float
    output_interval: float
    timeout: float
    communication_step: float | None = None  # a Co-Simulation FMU's largest (or fixed) step


@dataclass(frozen=True, eq=False)
class ScoredSamples:
    """Measured values, validity masks and weights, (samples, outputs), in ``outputs`` order."""

    outputs: tuple[str, ...]
    measured: np.ndarray
    valid: np.ndarray
    weights: np.ndarray

    @functools.cached_property
    def columns(self) -> tuple[tuple[int, np.ndarray, np.ndarray], ...]:
        """Per output of positive weight: its column, the indices of its valid samples and
        their measured values (what a batch is scored on)."""
        return tuple((j, np.flatnonzero(self.valid[:, j]), self.measured[self.valid[:, j], j])
                     for j in range(len(self.outputs)) if self.weights[j] > 0)


@dataclass(frozen=True, eq=False)
class Experiment:
    """One staged test: its config (verbatim and parsed) and its measurements.

    ``noise`` is the noise setting as configured (None, ``"pre-step"``, a number or a
    table); ``noise_sigma`` is its value per output, resolved at load time (None when no
    noise is configured).
    """

    name: str
    config_path: Path
    config_text: str
    model: str
    description: str
    data: MeasuredData
    outputs: dict[str, str]
    fixed: dict[str, float]
    estimate: tuple[EstimateSpec, ...]
    weights: dict[str, float]
    window: tuple[float, float]
    offset: bool
    noise: str | float | dict[str, float] | None
    noise_sigma: dict[str, float] | None
    pre_step_end: float | None
    simulation: SimulationSettings
    time_column: str = "time"  # as the data file names it (archives store the data under it)
    conversions: dict[str, Conversion] = field(default_factory=dict)  # outputs compared after a conversion
    inputs: tuple[InputSpec, ...] = ()  # model inputs driven by measured columns
    files: dict[str, MeasuredData] = field(default_factory=dict)  # inputs' other data files, by name
    noise_models: dict[str, RecorderNoise] = field(default_factory=dict)  # [noise]: whitened fitness
    recording: Recording = field(default_factory=Recording)  # the time base, masks, bridges: said

    def measured(self, output: str, data: MeasuredData | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The values ``output`` is compared with (converted as configured) and their mask."""
        data = self.data if data is None else data
        column = self.outputs[output]
        values, valid = np.where(data.valid[column], data.columns[column], np.nan), data.valid[column]
        conversion = self.conversions.get(output)
        return (values if conversion is None else conversion.apply(data.time, values, valid)), valid

    def source(self, spec: InputSpec) -> MeasuredData:
        """The recording an input is read from."""
        return self.files[spec.file] if spec.file is not None else self.data

    @functools.cached_property
    def input_table(self) -> InputTable | None:
        """The model's inputs over time, from their measured columns (None: no inputs).
        Masked and missing samples are bridged by linear interpolation between the valid
        ones (the loader has refused holes longer than an input allows: .recording); a
        derived ROCOF is :attr:`rocof_map` applied to the valid frequency samples."""
        if not self.inputs:
            return None
        columns = {}
        times = []
        for spec in self.inputs:
            source = self.source(spec)
            valid = source.valid[spec.column]
            values = spec.conversion.apply(source.time, source.columns[spec.column], valid)
            times.append(source.time)
            columns[spec.name] = (source.time, np.interp(source.time, source.time[valid], values[valid]))
        base = times[0] if all(np.array_equal(t, times[0]) for t in times) else np.unique(np.concatenate(times))
        table = InputTable.from_columns(base, {n: np.interp(base, t, v) for n, (t, v) in columns.items()})
        rocof = self.rocof_map
        if rocof is None:
            return table
        t, f = columns[FREQUENCY]
        values = np.interp(base, rocof.time, rocof.apply(f))
        return InputTable(table.time, table.names + (ROCOF,), np.column_stack([table.values, values]))

    @functools.cached_property
    def rocof_map(self) -> RocofOperator | None:
        """The derived ROCOF as a map of the recorded frequency (its valid samples, as
        stamped), split at the event (:func:`rapid_cosim.simulator.rocof.rocof_operator`);
        None where a ROCOF column is given or no frequency is recorded."""
        names = {s.name for s in self.inputs}
        if FREQUENCY not in names or ROCOF in names:
            return None
        spec = next(s for s in self.inputs if s.name == FREQUENCY)
        source = self.source(spec)
        breaks = () if self.pre_step_end is None else (self.pre_step_end,)
        return rocof_operator(source.time, WINDOW, breaks, source.valid[spec.column])

    def windowed_data(self) -> MeasuredData:
        """The measurements inside the fitness window (made once: every simulation asks)."""
        return self._windowed

    @functools.cached_property
    def _windowed(self) -> MeasuredData:
        return self.data.window(*self.window)

    @functools.cached_property
    def scored(self) -> ScoredSamples:
        """The windowed measurements as the fitness reads them, one column per output
        (made once: every simulation is scored against them)."""
        data, outputs = self.windowed_data(), tuple(self.outputs)
        window = np.flatnonzero((self.data.time >= data.time[0]) & (self.data.time <= data.time[-1]))
        pairs = [self.measured(o) for o in outputs]  # converted on the whole record (baselines), then cut
        return ScoredSamples(
            outputs=outputs,
            measured=np.column_stack([v[window] for v, _ in pairs]),
            valid=np.column_stack([ok[window] for _, ok in pairs]),
            weights=np.array([self.weights[o] for o in outputs]))
