"""Synthetic campaigns for the diagnosis studies: invented plants, hidden effects, and
recorders with the noise real ones have.

Plants: TG Type I with the field documentation's constants (Tc 0.4 s, T3 0.2 s, T4 1.5 s,
T5 6 s), droop R drawn in 0.045-0.065, governor lag Ts in 1.5-5 s, dispatch 0.6 or
0.8 pu. An effect of the catalogue (or two, or a variant of one, or one outside it) is
hidden at a size drawn from :data:`EFFECT_SIZES`, redrawn until it is visible in the data
(:data:`VISIBILITY`).

Recorders (:func:`recorder`): white noise of 0.6-1.2 x 10^-3 pu plus a slow component of
0.3 to 1 times that, its correlation that of an AR(1) with phi 0.8 to 0.95 at 10 Hz (a
correlation time of 0.45 to 1.95 s, simulated exactly on the sample times), a transducer
offset of up to 3 x 10^-3 pu, time stamps jittered by up to 0-5 ms, 16-bit quantisation
over a 2 pu span. The field tests' quiet data show white 1.2 x 10^-3 plus 0.8 x 10^-3
with phi 0.9 at 10 Hz: inside these ranges, which are not tuned to them.

Two kinds of campaign:

``staged`` (:data:`CAMPAIGN`): four staged tests shaped like the field's tests 2, 9, 10
and 4 (-200, -100, +100, +200 mHz, held 50 s and returned, 110 s at 10 Hz), the last held
out.

``event`` (:data:`EVENTS`): three recorded grid events driving the unit's measured
frequency, 120 s at 50 frames/s, the event 20 s in (:func:`rapid_cosim.experiment.synthetic.
under_frequency_event`): 3 % of generation lost, 2.5 % of load lost (the frequency
rises, the unit backs off), and, held out, 2 % of generation lost, each in a grid of
inertia 4-7 s and reserve lag 4-8 s drawn per event; PMU frequency noise of 1 mHz RMS
(correlated over 0.3 s). An event rate limit is asymmetric with one limit binding
throughout: opening at 0.002-0.006 pu/s (the unlimited unit rises at about 0.013 pu/s),
closing 2 to 4 times faster.

Effects outside the catalogue, invented so that the right answer is ``unexplained``
(:data:`FOREIGN`), act on the simulated power of the base model:

``boiler_dip``
    a boiler whose pressure sags when the turbine draws more steam: after each power
    change, a share ``k`` (0.4 to 0.7) of the difference between a lag of ``Ta`` (4 to 8 s)
    and one of ``Tb`` (20 to 40 s) of it is lost, so the power rises, sags and recovers.
``valve_curve``
    a valve whose flow characteristic is not linear at the dispatch point: power rises
    by ``1 + b`` and falls by ``1 - b`` times what droop asks (``b`` 0.08 to 0.15).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..compiler.source import ModelSource
from ..simulator import get_simulator
from ..experiment.synthetic import NoiseModel, synthesize, synthesize_event, under_frequency_event, write_event_experiment, \
    write_experiment
from .catalogue import EFFECTS, INPUT_BENCH, NONE, bench_name, check_effects, write_bench
from .result import AdvisedTest

# (df in Hz, return time in s or None); the last one is held out to confirm the verdict.
CAMPAIGN = ((-0.2, 60.0), (-0.1, 60.0), (0.1, 60.0), (0.2, 60.0))
# one step size only (tests 2, 4 and 1): a deadband cannot be told from a larger droop
SINGLE_SIZE = ((-0.2, 60.0), (0.2, 60.0), (-0.2, None))
DURATION_S, RATE_HZ, T_STEP = 110.0, 10.0, 10.0
# (share of generation lost: negative for load lost); the last one held out. Large enough
# for the unit to move by more than an output limit's material headroom (0.03 pu).
EVENTS = (0.05, -0.04, 0.035)
EVENT_DURATION_S, EVENT_RATE_HZ, T_EVENT, PMU_NOISE_HZ = 120.0, 50.0, 20.0, 1e-3

# The plant documentation's constants, as the configs fix them (the bench defaults); a
# doc_* case simulates the plant with one of them off.
DOCUMENTED = {"gov.Tc": 0.4, "gov.T3": 0.2, "gov.T4": 1.5, "gov.T5": 6.0}

Sizes = Callable[[np.random.Generator], dict[str, float]]


def _rates(low: float, high: float, ratio: tuple[float, float]) -> Sizes:
    return lambda g: (lambda r: {"gov.rate_open": r, "gov.rate_close": r * g.uniform(*ratio)})(g.uniform(low, high))


# realistic sizes that a staged campaign like CAMPAIGN reveals
EFFECT_SIZES: dict[str, Sizes] = {
    "deadband": lambda g: {"db.db": g.uniform(0.02, 0.04)},
    "rate_limit": _rates(0.004, 0.01, (1.5, 3.0)),
    "delay": lambda g: {"dly.T": g.uniform(0.8, 2.0)},
    "backlash": lambda g: {"gov.backlash": g.uniform(0.01, 0.03)},
    "load_controller": lambda g: {"gov.K_lc": g.uniform(0.008, 0.02)},
    "measurement_lag": lambda g: {"meas.T": g.uniform(1.0, 3.0)},
    "output_limit": lambda g: {"lim.headroom": g.uniform(0.02, 0.045)},
    # variants of form: a load controller on power filtered over 5-20 s; rate limits on the command
    "load_controller_filtered": lambda g: {"gov.K_lc": g.uniform(0.008, 0.02), "gov.T_f": g.uniform(5.0, 20.0)},
    "rate_limit_command": _rates(0.004, 0.01, (1.5, 3.0)),
    # a documented constant truly off by a factor 2, either way
    **{f"doc_{c}": (lambda c: lambda g: {f"gov.{c}": DOCUMENTED[f"gov.{c}"] * float(g.choice([0.5, 2.0]))})(c)
       for c in ("Tc", "T3", "T4", "T5")},
}
# events: an asymmetric rate limit, the opening one binding all through the rise
EVENT_SIZES: dict[str, Sizes] = {**EFFECT_SIZES, "rate_limit": _rates(0.002, 0.006, (2.0, 4.0))}


def _lag(t: np.ndarray, u: np.ndarray, T: float) -> np.ndarray:
    a = np.exp(-np.diff(t) / T)
    out = np.empty_like(u)
    out[0] = u[0]
    for k in range(u.size - 1):  # exact for a piecewise-linear input (the fine output grid)
        out[k + 1] = a[k] * out[k] + (1 - a[k]) * 0.5 * (u[k] + u[k + 1])
    return out


def _boiler_dip(t: np.ndarray, y: np.ndarray, v: dict[str, float]) -> np.ndarray:
    dp = y - y[0]
    return y - v["boiler.k"] * (_lag(t, dp, v["boiler.Ta"]) - _lag(t, dp, v["boiler.Tb"]))


def _valve_curve(t: np.ndarray, y: np.ndarray, v: dict[str, float]) -> np.ndarray:
    dp = y - y[0]
    return y[0] + dp * (1 + v["valve.b"] * np.sign(dp))


# Effects outside the catalogue: (sizes, transform of the base model's simulated power).
FOREIGN: dict[str, tuple[Sizes, Callable]] = {
    "boiler_dip": (lambda g: {"boiler.k": g.uniform(0.4, 0.7), "boiler.Ta": g.uniform(4.0, 8.0),
                              "boiler.Tb": g.uniform(20.0, 40.0)}, _boiler_dip),
    "valve_curve": (lambda g: {"valve.b": g.uniform(0.08, 0.15)}, _valve_curve),
}


def recorder(g: np.random.Generator) -> tuple[NoiseModel, float]:
    """A recorder's noise and its time stamps' jitter (s), as the module docstring says."""
    white = g.uniform(0.0006, 0.0012)
    tau = -0.1 / math.log(g.uniform(0.8, 0.95))
    noise = NoiseModel(white_sigma=white, ar1_sigma=white * g.uniform(0.3, 1.0), tau=tau,
                       offset=g.uniform(-0.003, 0.003), quantum=2.0 / 65536)
    return noise, g.uniform(0.0, 0.005)


@dataclass(frozen=True)
class Case:
    truth: str  # an effect name, "none", or effects joined by "+" (several hidden at once)
    seed: int
    plant: dict[str, float]
    effect_values: dict[str, float]
    steps: tuple  # staged: (df, t_return); event: (loss, inertia, reserve lag) per event
    noise: NoiseModel
    kind: str = "staged"  # or "event"
    jitter: float = 0.003

    @property
    def label(self) -> str:
        return f"{self.kind}-{self.truth.replace('+', '_and_')}-{self.seed}"

    @property
    def effects(self) -> tuple[str, ...]:
        """The catalogue effects hidden (a foreign one is applied to their output)."""
        return () if self.truth in (NONE, *FOREIGN) else tuple(self.truth.split("+"))

    @property
    def foreign(self) -> str | None:
        return self.truth if self.truth in FOREIGN else None


VISIBILITY = 1.5  # an effect is hidden only if its RMS contribution is this many noise levels


def draw_case(truth: str, seed: int, steps=CAMPAIGN, *, source: ModelSource, kind: str = "staged",
              visibility: float = VISIBILITY) -> Case:
    """A plant, an effect, a recorder; redrawn until the effect is visible in the data.

    Visible means: simulated with and without the effect (same plant, same tests), the
    responses differ by at least ``visibility`` times the noise level (RMS over the
    campaign, offset removed). An effect below that is not a discrepancy any method
    could show, and no gap could shrink by half once it is added.
    """
    g = np.random.default_rng([seed, zlib.crc32(truth.encode()), zlib.crc32(kind.encode())])
    noise, jitter = recorder(g)
    effects = () if truth in (NONE, *FOREIGN) else tuple(truth.split("+"))
    check_effects(effects)
    sizes = EVENT_SIZES if kind == "event" else EFFECT_SIZES
    for _ in range(50):
        plant = {"gov.R": g.uniform(0.045, 0.065), "gov.Ts": g.uniform(1.5, 5.0),
                 "gov.p_ref": float(g.choice([0.6, 0.8]))}
        values = {k: v for e in effects for k, v in sizes[e](g).items()}
        if truth in FOREIGN:
            values = FOREIGN[truth][0](g)
        shape = steps if kind == "staged" else tuple((loss, g.uniform(4.0, 7.0), g.uniform(4.0, 8.0))
                                                      for loss in EVENTS)
        case = Case(truth, seed, plant, values, tuple(shape), noise, kind, jitter)
        hidden = (truth,) if truth in FOREIGN else effects
        if not hidden or all(effect_rms(case, source=source, only=e) >= visibility * noise.sigma
                             for e in hidden):
            return case
    raise RuntimeError(f"no visible {truth} drawn in 50 tries; widen the effect's sizes")


def _bench_fmu(effects: tuple[str, ...], source: ModelSource, kind: str = "staged"):
    """The bench of ``effects``; one not in the package is generated into the (study's) copy."""
    base = INPUT_BENCH if kind == "event" else "iGrGen.TestBenches.StagedTest"
    name = bench_name(effects, base)
    if name.startswith("iGrGen.Diagnosed."):
        write_bench(source.package_path, effects, name, base=base, description="synthetic study: effects hidden", register=False)
    return source.fmu(name)


def _event_frequency(t: np.ndarray, event: tuple) -> np.ndarray:
    loss, inertia, lag = event
    return under_frequency_event(t, t_event=T_EVENT, loss=loss, inertia=inertia, reserve_lag=lag)


def _responses(case: Case, sim, values: dict, times: np.ndarray, transform=None) -> list[np.ndarray]:
    """The campaign's responses on ``times`` (one per test or event)."""
    out = []
    for step in case.steps:
        if case.kind == "event":
            t = np.arange(0.0, EVENT_DURATION_S, 0.02)
            y = sim.simulate({**case.plant, **values}, output_times=t, input_time=t,
                             inputs={"f_dev": _event_frequency(t, step)})["pm"]
        else:
            df, t_return = step
            fixed = {"gov.p_ref": case.plant["gov.p_ref"], "src.df": df, "src.t_step": T_STEP,
                     **({"src.t_return": t_return} if t_return is not None else {})}
            traj = sim.simulate({**fixed, **case.plant, **values}, stop_time=DURATION_S, output_interval=0.01)
            t, y = traj.time, traj["pm"]
        if transform is not None:
            y = transform(t, y)
        out.append(np.interp(times, t, y))
    return out


def effect_rms(case: Case, *, source: ModelSource, only: str) -> float:
    """RMS difference the effect ``only`` (one of the case's) makes to the campaign's
    responses, offset removed."""
    without = get_simulator(_bench_fmu((), source, case.kind))
    foreign = only in FOREIGN
    rate = EVENT_RATE_HZ if case.kind == "event" else RATE_HZ
    times = np.arange(0.0, (EVENT_DURATION_S if case.kind == "event" else DURATION_S) + 1e-9, 1 / rate)
    if foreign:
        a = _responses(case, without, {}, times, lambda t, y: FOREIGN[only][1](t, y, case.effect_values))
    else:
        own = {p.name for p in EFFECTS[only].parameters}
        a = _responses(case, get_simulator(_bench_fmu((only,), source, case.kind)),
                       {k: v for k, v in case.effect_values.items() if k in own}, times)
    b = _responses(case, without, {}, times)
    return float(np.sqrt(np.mean([np.mean((d - d.mean()) ** 2) for d in (x - y for x, y in zip(a, b))])))


ESTIMATE = {"gov.R": {"min": 0.02, "max": 0.12, "label": "R"}, "gov.Ts": {"min": 0.1, "max": 20.0, "label": "Ts"}}


def write_campaign(case: Case, folder: Path, *, source: ModelSource) -> list[Path]:
    """Configs of the case's tests (or events), their data simulated with what is hidden."""
    fmu = _bench_fmu(case.effects, source, case.kind)
    rng = np.random.default_rng([case.seed, 7919])
    transform = None
    if case.foreign:
        transform = lambda tt, yy: FOREIGN[case.foreign][1](tt, yy, case.effect_values)  # noqa: E731
    values = {} if case.foreign else case.effect_values
    paths = []
    for k, step in enumerate(case.steps):
        if case.kind == "event":
            fixed = {"gov.p_ref": case.plant["gov.p_ref"], **DOCUMENTED}
            t, f_dev, y = synthesize_event(fmu, {**fixed, **case.plant, **values}, duration=EVENT_DURATION_S,
                                           rate=EVENT_RATE_HZ, t_event=T_EVENT, f_noise=PMU_NOISE_HZ,
                                           p_noise=case.noise, rng=rng, jitter=case.jitter, transform=transform,
                                           event={"loss": step[0], "inertia": step[1], "reserve_lag": step[2]})
            paths.append(write_event_experiment(
                folder / f"event{k + 1}", time=t, frequency=50.0 + f_dev, values=y, fixed=fixed, estimate=ESTIMATE,
                t_event=T_EVENT, description=f"synthetic: {case.truth} hidden, {100 * step[0]:+.1f} % lost"))
            continue
        df, t_return = step
        fixed = {"gov.p_ref": case.plant["gov.p_ref"], "src.df": df, "src.t_step": T_STEP, **DOCUMENTED}
        if t_return is not None:
            fixed["src.t_return"] = t_return
        t, y = synthesize(fmu, {**fixed, **case.plant, **values}, duration=DURATION_S, rate=RATE_HZ,
                          jitter=case.jitter, noise=case.noise, rng=rng, transform=transform)
        paths.append(write_experiment(
            folder / f"step{k + 1}", model="iGrGen.TestBenches.StagedTest", time=t, values=y, fixed=fixed,
            estimate=ESTIMATE, fitness={"offset": True, "noise": "pre-step", "pre_step_end": T_STEP},
            description=f"synthetic: {case.truth} hidden, df = {1000 * df:+.0f} mHz"))
    return paths


def write_advised(case: Case, test: AdvisedTest, folder: Path, *, source: ModelSource) -> list[Path]:
    """Configs of an advised test (its steps, hold and dispatch), its data recorded from the case's plant with fresh noise: what the
    user of the advice does next."""
    fmu = _bench_fmu(case.effects, source, case.kind)
    rng = np.random.default_rng([case.seed, 104729, zlib.crc32(case.truth.encode())])
    t_step, hold = test.t_step_s, test.hold_s
    paths = []
    for k, df in enumerate(test.steps_hz):
        fixed = {"gov.p_ref": test.p_ref, "src.df": df, "src.t_step": t_step, "src.t_return": t_step + hold,
                 **DOCUMENTED}
        # the plant's hidden values over the documented ones (a doc_* case), at the advised dispatch
        plant = {**fixed, **case.plant, **case.effect_values, "gov.p_ref": test.p_ref}
        t, y = synthesize(fmu, plant, duration=t_step + 2 * hold,
                          rate=RATE_HZ, jitter=case.jitter, noise=case.noise, rng=rng)
        paths.append(write_experiment(
            folder / f"advised{k + 1}", model="iGrGen.TestBenches.StagedTest", time=t, values=y, fixed=fixed,
            estimate=ESTIMATE, fitness={"offset": True, "noise": "pre-step", "pre_step_end": t_step},
            description=f"synthetic: the advised test, df = {1000 * df:+.0f} mHz held {hold:.0f} s"))
    return paths
