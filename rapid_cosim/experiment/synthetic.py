"""Synthetic staged tests from the project's own models: data whose truth is known.

For checking that a method recovers known parameters, that a Bayesian interval covers
them as often as it claims, and that the discrepancy workflow names an effect hidden in
the data. Noise is white plus a slow correlated component (AR(1) per sample, or an
Ornstein-Uhlenbeck process of correlation time ``tau`` on the actual, jittered time
stamps), the recorder's clock jitters, its A/D converter quantises, and the transducer
may carry an offset: the features of the field recordings.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import ParameterError
from ..noise import RecorderNoise
from ..simulator import Simulator, get_simulator


@dataclass(frozen=True)
class NoiseModel:
    """``e_k = phi * e_{k-1} + a_k`` (AR(1), stationary std ``ar1_sigma``) plus white
    ``white_sigma``; with ``tau`` (s) the slow part is instead an Ornstein-Uhlenbeck
    process of that correlation time, exact on irregular time stamps (``phi`` unused).
    ``quantum``: the recorder's resolution (pu per count); the recorded value is rounded
    to it (e.g. 16 bits over a 2 pu span: 2 / 65536)."""

    white_sigma: float = 0.0
    ar1_sigma: float = 0.0
    phi: float = 0.0
    offset: float = 0.0
    tau: float | None = None
    quantum: float = 0.0

    @property
    def sigma(self) -> float:
        """Standard deviation of the noise (offset aside)."""
        return float(np.hypot(self.white_sigma, self.ar1_sigma))

    def sample(self, n: int, rng: np.random.Generator, times: np.ndarray | None = None) -> np.ndarray:
        """``n`` noise values (at ``times`` when the slow part is continuous in time)."""
        if self.tau is not None:
            if times is None:
                raise ParameterError("a noise model with tau (a slow part continuous in time) needs the sample times")
            comps = ((self.ar1_sigma, self.tau),) if self.ar1_sigma > 0 else ()
            if not comps and self.white_sigma == 0:
                return np.full(n, self.offset)
            return RecorderNoise(self.white_sigma, comps, float(np.median(np.diff(times)))).sample(times, rng) \
                + self.offset
        e = self.white_sigma * rng.standard_normal(n)
        if self.ar1_sigma > 0:
            a = self.ar1_sigma * np.sqrt(1 - self.phi ** 2) * rng.standard_normal(n)
            ar = np.empty(n)
            ar[0] = self.ar1_sigma * rng.standard_normal()
            for k in range(1, n):
                ar[k] = self.phi * ar[k - 1] + a[k]
            e += ar
        return e + self.offset


def jittered_times(duration: float, rate: float, jitter: float, rng: np.random.Generator) -> np.ndarray:
    """Recorder timestamps: nominal 1/rate spacing, each off by up to ``jitter`` seconds."""
    nominal = np.arange(0.0, duration, 1.0 / rate)
    t = nominal + rng.uniform(-jitter, jitter, nominal.size)
    t[0] = max(t[0], 0.0)
    return np.maximum.accumulate(t + np.arange(t.size) * 1e-9)  # strictly increasing


def synthesize(fmu: str | Path | Simulator, parameters: Mapping[str, float], *, duration: float,
               rate: float = 10.0, jitter: float = 0.003, noise: NoiseModel = NoiseModel(),
               rng: np.random.Generator, output: str = "pm", output_interval: float = 0.01,
               transform=None) -> tuple[np.ndarray, np.ndarray]:
    """(time, measured output) of one staged test simulated with ``parameters``;
    ``transform(time, values)`` changes the simulated output first (a plant that the
    model does not describe)."""
    sim = fmu if isinstance(fmu, Simulator) else get_simulator(fmu)
    t = jittered_times(duration, rate, jitter, rng)
    traj = sim.simulate(parameters, stop_time=float(t[-1]), output_interval=output_interval, outputs=[output])
    clean = traj[output] if transform is None else transform(np.asarray(traj.time), np.asarray(traj[output]))
    y = np.interp(t, traj.time, clean)
    return t, quantise(y + noise.sample(t.size, rng, t), noise.quantum)


def quantise(y: np.ndarray, quantum: float) -> np.ndarray:
    """Values rounded to the recorder's resolution (unchanged for ``quantum`` 0)."""
    return np.round(y / quantum) * quantum if quantum > 0 else y


def write_csv(path: str | Path, time: np.ndarray, values: np.ndarray, column: str = "pm") -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w") as f:
        f.write(f"time,{column}\n")
        for t, v in zip(time, values):
            f.write(f"{t:.4f},{v:.6f}\n")
    return path


def write_experiment(folder: str | Path, *, model: str, time: np.ndarray, values: np.ndarray,
                     fixed: Mapping[str, float], estimate: Mapping[str, Mapping], name: str | None = None,
                     fitness: Mapping | None = None, simulation: Mapping | None = None,
                     description: str = "synthetic staged test") -> Path:
    """A config folder (config.toml + data.csv) that ``load_experiment`` reads."""
    from . import render_config

    folder = Path(folder)
    write_csv(folder / "data.csv", time, values)
    sections = {
        "experiment": {"name": name or folder.name, "model": model, "description": description},
        "data": {"file": "data.csv", "time": "time", "outputs": {"pm": "pm"}},
        "fixed": dict(fixed),
        "estimate": {k: dict(v) for k, v in estimate.items()},
        "fitness": dict(fitness or {"offset": True}),
        "simulation": dict(simulation or {"output_interval": 0.05, "timeout": 10.0}),
    }
    path = folder / "config.toml"
    path.write_text(render_config(sections))
    return path


def write_event_experiment(folder: str | Path, *, time: np.ndarray, frequency: np.ndarray, values: np.ndarray,
                           fixed: Mapping[str, float], estimate: Mapping[str, Mapping], t_event: float,
                           model: str = "iGrGen.TestBenches.FrequencyInput", name: str | None = None,
                           description: str = "synthetic recorded event") -> Path:
    """A config folder for a recorded event: ``data.csv`` with the recorded frequency
    (Hz) and power (pu); the frequency drives the model's ``f_dev`` as a deviation from
    50 Hz with its pre-event level removed."""
    from . import render_config

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    with (folder / "data.csv").open("w") as f:
        f.write("time,FREQ,P\n")
        for t, fr, v in zip(time, frequency, values):
            f.write(f"{t:.4f},{fr:.6f},{v:.6f}\n")
    sections = {
        "experiment": {"name": name or folder.name, "model": model, "description": description},
        "data": {"file": "data.csv", "time": "time", "outputs": {"pm": "P"}},
        "inputs": {"f_dev": {"column": "FREQ", "unit": "Hz", "convert": "deviation", "nominal": 50.0,
                             "baseline": "pre-event"}},
        "fixed": {"f_nom": 50.0, **fixed},
        "estimate": {k: dict(v) for k, v in estimate.items()},
        "fitness": {"offset": True, "noise": "pre-step", "pre_step_end": float(t_event)},
        "simulation": {"timeout": 10.0},
    }
    path = folder / "config.toml"
    path.write_text(render_config(sections))
    return path


# --------------------------------------------------------------------------- recorded disturbances


def under_frequency_event(time: np.ndarray, *, t_event: float, loss: float = 0.03, inertia: float = 5.0,
                          damping: float = 1.0, reserve_droop: float = 0.05, reserve_lag: float = 6.0,
                          f_nom: float = 50.0) -> np.ndarray:
    """Frequency deviation (Hz) of a grid that loses ``loss`` pu of generation at
    ``t_event``: inertia ``2H df/dt = -loss - D df + p_r`` and an aggregate primary
    reserve ``Tg dp_r/dt = -df / Rg - p_r`` (all pu on the grid's base). The frequency
    falls at ``loss / 2H`` at first, turns at a nadir when the reserve catches up, and
    recovers to ``-loss / (D + 1 / Rg)``: the shape of a recorded under-frequency event."""
    a = np.array([[-damping / (2 * inertia), 1 / (2 * inertia)],
                  [-1 / (reserve_droop * reserve_lag), -1 / reserve_lag]])
    b = np.array([-loss / (2 * inertia), 0.0])
    lam, v = np.linalg.eig(a)  # the exact step response: x = A^-1 (exp(A tau) - I) b
    c = np.linalg.solve(v, np.linalg.solve(a, b))
    tau = np.clip(np.asarray(time, dtype=float) - t_event, 0.0, None)
    x = (v @ (c[:, None] * (np.exp(np.outer(lam, tau)) - 1.0))).real
    return f_nom * x[0]


def pmu_noise(n: int, *, rate: float, sigma: float, window: float, rng: np.random.Generator) -> np.ndarray:
    """Noise of a PMU's frequency estimate: ``sigma`` RMS, correlated over the estimator's
    ``window`` seconds (a first-order filter of white noise)."""
    from scipy.signal import lfilter

    a = np.exp(-1.0 / (rate * window))
    start = sigma * rng.standard_normal()  # drawn from the stationary distribution
    white = rng.standard_normal(n) * sigma * np.sqrt((1 + a) / (1 - a))
    out, _ = lfilter([1 - a], [1.0, -a], white[1:], zi=[a * start])
    return np.concatenate([[start], out])


def synthesize_event(fmu: str | Path | Simulator, parameters: Mapping[str, float], *, duration: float,
                     rate: float, t_event: float, f_noise: float, p_noise: NoiseModel, rng: np.random.Generator,
                     input: str = "f_dev", output: str = "pm", event: Mapping | None = None, jitter: float = 0.0,
                     transform=None, runner: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(time, measured frequency deviation in Hz, measured output) of a unit riding
    through a grid event (:func:`under_frequency_event`; a negative ``loss`` is a load
    lost, and the frequency rises): the model is driven by the true frequency; the
    recorder samples at times off their grid by up to ``jitter`` s, adds PMU noise to the
    frequency and ``p_noise`` to the output. ``transform(time, values)`` changes the
    simulated output first (a plant the model does not describe); ``runner`` simulates it
    (default: the simulator's)."""
    sim = fmu if isinstance(fmu, Simulator) else get_simulator(fmu)
    t = jittered_times(duration, rate, jitter, rng) if jitter > 0 else np.arange(0.0, duration, 1.0 / rate)
    f_true = under_frequency_event(t, t_event=t_event, **dict(event or {}))
    traj = sim.simulate(parameters, output_times=t, outputs=[output], input_time=t, inputs={input: f_true},
                        runner=runner)
    f_meas = f_true + pmu_noise(t.size, rate=rate, sigma=f_noise, window=0.3, rng=rng)
    clean = traj[output] if transform is None else transform(t, np.asarray(traj[output]))
    return t, f_meas, quantise(clean + p_noise.sample(t.size, rng, t), p_noise.quantum)
