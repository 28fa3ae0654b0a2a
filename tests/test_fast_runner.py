"""The exponential runner ("exponential", rapid_cosim/simulator/expint.c): within 5e-5 pu of a
tight reference on recorded noisy events, staged tests and the standard governors with
their limits engaged; the semantics of the CVODE runner (events, input steps, typed
outputs, failures, time-outs); the fallback to CVODE where it does not apply; and runs
that repeat bit for bit. No test here asserts on timing."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from c_fmus import build_c_fmu
from reference_models import EFFECT_DEFAULTS, Reference
from test_reference import CASES as STAGED_CASES
from test_reference import EFFECT_ACTIVE
from test_reference_standard import CASES as STANDARD_CASES

from rapid_cosim.errors import SimulationError, SimulationTimeout
from rapid_cosim.simulator import InputTable, Simulator
from rapid_cosim.simulator.compiled import OK, TIMEOUT
from rapid_cosim.experiment.synthetic import jittered_times, pmu_noise, under_frequency_event

ACCURACY = 5e-5  # pu, against CVODE at rtol 1e-10
TIGHT = 1e-10


def _pmu_event(seed: int = 0, duration: float = 120.0, loss: float = 0.03, white: bool = False):
    """A recorded under-frequency event as a PMU gives it: 50 frames/s with a few ms of
    jitter on the time stamps, 1 mHz RMS of noise on the frequency (Hz)."""
    rng = np.random.default_rng(seed)
    t = jittered_times(duration, 50.0, 0.003, rng)
    noise = 1e-3 * rng.standard_normal(t.size) if white else pmu_noise(t.size, rate=50.0, sigma=1e-3, window=0.3,
                                                                       rng=rng)
    return t, under_frequency_event(t, t_event=20.0, loss=loss) + noise


def _runs(fmu, params, **kw):
    """(exponential runner, compiled runner, tight reference) outputs and the exponential
    run's counters."""
    sim = Simulator(fmu)
    prepared = sim.prepare(list(params), runner="exponential", **kw)
    values = np.array([list(params.values())])
    fast = prepared.run(values)
    assert fast.ok.all(), fast.messages
    compiled = sim.prepare(list(params), runner="compiled", **kw).run(values)
    tight = Simulator(fmu, relative_tolerance=TIGHT).prepare(list(params), runner="compiled", **kw).run(values)
    return fast.values[0], compiled.values[0], tight.values[0], prepared._call.counters


@pytest.fixture(scope="module")
def c_fmus(tmp_path_factory):
    folder = tmp_path_factory.mktemp("c_fmus_fast")
    return {name: build_c_fmu(name, folder) for name in ("BouncingBall", "Counter", "DroopPlant")}


@pytest.fixture(scope="module")
def rate_limited_input_bench(repo, tmp_path_factory):
    """FrequencyInput with the valve's rate limits (the catalogue's rate_limit effect),
    generated into a copy of the package as the diagnosis does."""
    from rapid_cosim.compiler import build_models
    from rapid_cosim.diagnose.catalogue import INPUT_BENCH, bench_name, write_bench

    root = tmp_path_factory.mktemp("rate_pkg")
    shutil.copytree(repo / "modelica" / "iGrGen", root / "iGrGen")
    name = bench_name(("rate_limit",), INPUT_BENCH)
    write_bench(root / "iGrGen", ("rate_limit",), name, base=INPUT_BENCH)
    return build_models([name], package=root / "iGrGen", fmu_dir=root / "fmus", log=lambda *_: None)[0].fmu


# --------------------------------------------------------------------------- accuracy


@pytest.mark.parametrize("white", [False, True], ids=["pmu-noise", "white-noise"])
@pytest.mark.parametrize("case", [{"gov.Ts": 2.0}, {"gov.Ts": 0.1}, {"gov.Ts": 0.5, "gov.pmax": 0.63}],
                         ids=["Ts=2", "Ts=0.1", "clamped-at-pmax"])
def test_noisy_recorded_event_within_the_tight_reference(fmus, case, white):
    t, f = _pmu_event(white=white)
    fast, compiled, tight, counters = _runs(fmus["FrequencyInput"], case, output_times=t, input_time=t,
                                            inputs={"f_dev": f}, outputs=["pm", "gov.pin"])
    assert np.max(np.abs(fast[:, 0] - tight[:, 0])) < ACCURACY
    assert np.max(np.abs(fast - compiled)) < 1e-4  # and close to what the CVODE runner gives
    assert np.ptp(tight[:, 0]) > 0.01
    assert counters["sets"] == 1 and counters["sets_cvode"] == 0
    assert counters["evaluations"] < 1.2 * t.size  # about one model evaluation per sample
    if "gov.pmax" in case:  # the limiter engaged: the linearisation was renewed
        assert np.mean(tight[:, 1] == 0.63) > 0.05
        assert counters["relinearisations"] > 0


def test_noisy_event_with_binding_rate_limits(rate_limited_input_bench):
    t, f = _pmu_event(seed=3, loss=0.05)
    params = {"gov.rate_open": 0.004, "gov.rate_close": 0.004, "gov.Ts": 1.0}
    fast, _, tight, counters = _runs(rate_limited_input_bench, params, output_times=t, input_time=t,
                                     inputs={"f_dev": f}, outputs=["pm", "gov.xg1"])
    assert np.max(np.abs(fast[:, 0] - tight[:, 0])) < ACCURACY
    slope = np.diff(tight[:, 1]) / np.diff(t)
    assert slope.max() == pytest.approx(0.004, rel=0.05)  # the limit binds
    assert counters["relinearisations"] > 0


def test_staged_test_1_within_the_tight_reference(repo, fmus):
    from rapid_cosim.experiment import load_experiment

    exp = load_experiment(repo / "experiments" / "test1" / "config.toml")
    t = exp.windowed_data().time
    sim = Simulator(fmus["StagedTest"])
    fixed = {k: v for k, v in exp.fixed.items() if k in sim.parameters}
    for params in ({**fixed, "gov.R": 0.05, "gov.Ts": 2.0}, {**fixed, "gov.R": 0.03, "gov.Ts": 0.1},
                   {**fixed, "gov.pmax": 0.65, "gov.R": 0.05, "gov.Ts": 1.0}):
        fast, _, tight, counters = _runs(fmus["StagedTest"], params, output_times=t, outputs=["pm"])
        assert np.max(np.abs(fast - tight)) < ACCURACY
        assert counters["evaluations"] < 1.1 * t.size
    assert np.ptp(tight) > 0.01


@pytest.mark.parametrize("model, case", [(m, c) for m, cases in STANDARD_CASES.items() for c in cases])
def test_standard_governors_on_a_recorded_event_with_limits_engaged(fmus, model, case):
    """Each standard governor's FrequencyInput bench, driven by a deep noisy event (about
    0.5 Hz), on the parameter sets that engage its limiters, rate limits and gate."""
    t, f = _pmu_event(seed=1, duration=60.0, loss=0.06)
    params = {k: v for k, v in STANDARD_CASES[model][case].items() if k.startswith("gov.")}
    fast, _, tight, _ = _runs(fmus[f"FrequencyInput{model}"], params, output_times=t, input_time=t,
                              inputs={"f_dev": f}, outputs=["pm"])
    assert np.max(np.abs(fast - tight)) < ACCURACY
    assert np.ptp(tight) > 0.01


@pytest.mark.parametrize("model, case", [(m, c) for m, cases in STANDARD_CASES.items() for c in cases])
def test_standard_governors_staged_within_the_tight_reference(fmus, model, case):
    params = STANDARD_CASES[model][case]
    t = jittered_times(60.0, 10.0, 0.003, np.random.default_rng(2))
    fast, _, tight, _ = _runs(fmus[f"StagedTest{model}"], params, output_times=t, outputs=["pm"])
    assert np.max(np.abs(fast - tight)) < ACCURACY


@pytest.mark.parametrize("case", list(STAGED_CASES))
@pytest.mark.parametrize("bench", list(EFFECT_DEFAULTS))
def test_effect_benches_match_scipy(fmus, bench, case):
    """The independent scipy integration of tests/reference_models.py, as the CVODE runner
    is checked in test_reference.py."""
    sim = Simulator(fmus[bench])
    ref = Reference(bench, {**STAGED_CASES[case], **EFFECT_ACTIVE.get(bench, {})})
    params = {k: v for k, v in ref.p.items() if sim.parameters[k].settable}
    traj = sim.simulate(params, stop_time=60.0, output_interval=0.05, runner="exponential")
    assert np.max(np.abs(traj["pm"] - ref.simulate(traj.time))) < 1e-4


# --------------------------------------------------------------------------- semantics


def test_input_ramps_and_steps_match_the_analytic_response(c_fmus):
    """The DroopPlant (a C FMU) driven by a ramp, then a step back (a time written twice):
    the exact solution, the step taken as a time event; output times off the input rows."""
    R, T, p_ref = 0.05, 2.0, 0.6
    table = InputTable.from_columns([0.0, 5.0, 10.0, 20.0, 20.0, 40.0], {"dw": [0, 0, -0.004, -0.004, 0, 0]})
    t = np.linspace(0.0, 40.0, 801)
    dense = np.linspace(0.0, 40.0, 400001)
    target = p_ref - np.array([table.at(tt) for tt in dense])[:, 0] / R
    p = np.empty_like(dense)
    p[0] = p_ref
    a = np.exp(-np.diff(dense) / T)
    for k in range(dense.size - 1):
        p[k + 1] = a[k] * p[k] + (1 - a[k]) * 0.5 * (target[k] + target[k + 1])
    traj = Simulator(c_fmus["DroopPlant"]).simulate({"R": R, "T": T}, output_times=t, inputs=table,
                                                    runner="exponential")
    assert np.max(np.abs(traj["p"] - np.interp(t, dense, p))) < 2e-5
    at_step = np.flatnonzero(t == 20.0)[0]
    assert traj["p"][at_step] == pytest.approx(np.interp(20.0, dense, p), abs=2e-5)  # the value after it


def test_events_and_mixed_grids_as_the_cvode_runner_gives_them(fmus):
    """FMU time events (a step and its return), an input step, inputs at 25 Hz with
    outputs at 10 Hz jittered, a start after 0: the two runners agree."""
    sim = Simulator(fmus["StagedTest"])
    t = np.unique(np.concatenate([[10.0, 30.0], np.random.default_rng(4).uniform(2.0, 60.0, 500)]))
    params = {"gov.Ts": 1.5, "src.t_step": 10.0, "src.t_return": 30.0}
    kw = dict(output_times=t, start_time=2.0)
    fast = sim.simulate(params, runner="exponential", **kw)
    cvode = sim.simulate(params, runner="compiled", **kw)
    assert np.max(np.abs(fast["pm"] - cvode["pm"])) < 2e-5
    # values at an event are those after it
    at = sim.simulate(params, output_times=np.array([9.99, 10.0]), outputs=["gov.pin"], runner="exponential")
    assert at["gov.pin"][0] == pytest.approx(0.6) and at["gov.pin"][1] == pytest.approx(0.68)

    fi = Simulator(fmus["FrequencyInput"])
    rows = np.arange(0.0, 40.0, 0.04)
    f = -0.1 * np.clip(rows - 5.0, 0.0, 2.0) / 2.0 + 1e-3 * np.random.default_rng(5).standard_normal(rows.size)
    before, after = rows < 20.0, rows > 20.0
    time = np.concatenate([rows[before], [20.0, 20.0], rows[after]])  # a step at 20 s, back to 0
    values = np.concatenate([f[before], [np.interp(20.0, rows, f), 0.0], np.zeros(after.sum())])
    out = jittered_times(40.0, 10.0, 0.003, np.random.default_rng(6))
    kw = dict(output_times=out, input_time=time, inputs={"f_dev": values}, outputs=["pm"])
    fast = fi.simulate({"gov.Ts": 1.0}, runner="exponential", **kw)
    cvode = fi.simulate({"gov.Ts": 1.0}, runner="compiled", **kw)
    tight = Simulator(fmus["FrequencyInput"], relative_tolerance=TIGHT).simulate({"gov.Ts": 1.0}, runner="compiled",
                                                                                 **kw)
    assert np.max(np.abs(fast["pm"] - tight["pm"])) < ACCURACY
    assert np.max(np.abs(fast["pm"] - cvode["pm"])) < 1e-4


@pytest.mark.parametrize("runner", ["compiled", "exponential"])
@pytest.mark.parametrize("bench", ["plain", "rate-limited"])
def test_an_output_time_within_rounding_of_an_event_is_the_value_after_it(fmus, rate_limited_input_bench,
                                                                            bench, runner):
    """An input step (a time event) at 20 s and output times a few rounding units after it:
    CVODE, reinitialised at the event, refuses a first step that short ("tout too close to
    t0"); the runner ends the step at the event instead (a fleet unit's plot failed there).
    Without event indicators and with them (the rate-limited bench's)."""
    fmu = fmus["FrequencyInput"] if bench == "plain" else rate_limited_input_bench
    rows = np.arange(0.0, 40.0, 0.04)
    before, after = rows < 20.0, rows > 20.0
    time = np.concatenate([rows[before], [20.0, 20.0], rows[after]])
    values = np.concatenate([-0.05 * np.ones(before.sum() + 1), np.zeros(after.sum() + 1)])
    close = [20.0 + k * np.spacing(20.0) for k in (1, 4, 32)]
    out = np.array([19.0, 20.0, *close, 21.0])
    traj = Simulator(fmu).simulate({}, output_times=out, input_time=time, inputs={"f_dev": values},
                                   outputs=["pm"], runner=runner)
    assert np.all(np.isfinite(traj["pm"]))
    np.testing.assert_allclose(traj["pm"][2:5], traj["pm"][1], atol=1e-12)
    assert abs(traj["pm"][0] - traj["pm"][-1]) > 1e-3  # the step moved the governor


def test_integer_and_boolean_outputs(c_fmus):
    traj = Simulator(c_fmus["Counter"]).simulate({"period": 0.5}, stop_time=2.2, output_interval=0.25,
                                                 outputs=["count", "odd", "x"], runner="exponential")
    assert list(traj["count"]) == [0, 0, 1, 1, 2, 2, 3, 3, 4, 4]
    assert list(traj["odd"]) == [0, 0, 1, 1, 0, 0, 1, 1, 0, 0]
    assert traj["x"][-1] == pytest.approx(0.5 * (1 + 2 + 3) + 0.25 * 4, abs=1e-6)


def test_state_events_fall_back_to_the_cvode_runner(c_fmus):
    """The bouncing ball has an event indicator: every set runs through runner.c's CVODE
    path, so the outputs are the compiled runner's, bit for bit."""
    sim = Simulator(c_fmus["BouncingBall"])
    kw = dict(output_times=np.linspace(0.0, 3.0, 601), outputs=["h", "v", "bounces"])
    values = np.array([[0.7], [0.5], [0.9]])
    prepared = sim.prepare(["e"], runner="exponential", **kw)
    fast = prepared.run(values)
    compiled = sim.prepare(["e"], runner="compiled", **kw).run(values)
    assert fast.ok.all()
    np.testing.assert_array_equal(fast.values, compiled.values)
    counters = prepared._call.counters
    assert counters["sets_cvode"] == 3 and counters["steps"] == 0
    assert fast.values[0, -1, 2] >= 4  # it bounced


def test_a_bad_set_fails_alone_with_a_message(blowup):
    """x' = a x^2 reaches infinity at t = 1/a: the sets with a >= 0.5 fail (the integrator
    misses, CVODE takes the step and fails), the others run on."""
    values = np.array([[0.1], [1.0], [0.2], [5.0], [0.3]])
    batch = blowup.simulate_batch(["a"], values, stop_time=2.0, output_interval=0.1, outputs=["x"],
                                  runner="exponential")
    assert np.all(batch.ok[[0, 2, 4]]) and not np.any(batch.ok[[1, 3]])
    assert batch.values[4, -1, 0] == pytest.approx(1 / (1 - 0.3 * 2.0), rel=1e-4)
    assert np.all(np.isnan(batch.values[1])) and "Blowup failed with a=1" in batch.messages[1]
    with pytest.raises(SimulationError, match="Blowup failed"):
        blowup.simulate({"a": 1.0}, stop_time=2.0, output_interval=0.1, outputs=["x"], runner="exponential")
    ok = blowup.simulate({"a": 0.1}, stop_time=2.0, output_interval=0.1, outputs=["x"], runner="exponential")
    assert ok["x"][-1] == pytest.approx(1 / (1 - 0.1 * 2.0), rel=1e-4)


def test_a_timed_out_set_does_not_stall_the_batch(fmus):
    sim = Simulator(fmus["StagedTest"], timeout=1e-7)
    batch = sim.simulate_batch(["gov.Ts"], np.array([[1.0], [2.0]]), stop_time=60.0, output_interval=0.05,
                               runner="exponential")
    assert np.all(batch.status == TIMEOUT) and all("wall-clock" in m for m in batch.messages)
    with pytest.raises(SimulationTimeout, match="time-out"):
        sim.simulate({}, stop_time=60.0, output_interval=0.05, runner="exponential")
    sim.timeout = None
    assert sim.simulate_batch(["gov.Ts"], np.array([[1.0]]), stop_time=60.0, output_interval=0.05,
                              runner="exponential").status[0] == OK


@pytest.mark.parametrize("n", range(1, 13))
def test_the_exponentials_sized_products_give_the_plain_loops_numbers(n):
    """expint.c multiplies matrices of up to 12 states with copies made for each size
    (a row held in registers): the same numbers as its plain loop, bit for bit (larger
    ones take the plain loop itself)."""
    import ctypes

    from rapid_cosim.simulator.compiled import _library

    rng = np.random.default_rng(n)
    a = rng.standard_normal((n, n)) * 10.0 ** rng.integers(-8, 8, (n, n))
    b = rng.standard_normal((n, n)) * 10.0 ** rng.integers(-8, 8, (n, n))
    a[rng.random((n, n)) < 0.3] = 0.0  # the Jacobians are sparse: zeros and signed zeros
    b[0, 0] = -0.0
    sized, plain = np.empty((n, n)), np.empty((n, n))
    lib = _library()
    for out, flag in ((sized, 0), (plain, 1)):
        lib.rc_mat_mul(n, a.ctypes.data, b.ctypes.data, out.ctypes.data, ctypes.c_int(flag))
    assert sized.tobytes() == plain.tobytes()
    np.testing.assert_allclose(sized, a @ b, rtol=1e-12, atol=1e-12 * float((np.abs(a) @ np.abs(b)).max()))
    lib.rc_mat_mul(n, a.ctypes.data, a.ctypes.data, sized.ctypes.data, ctypes.c_int(0))  # a a, as Phi Phi is
    lib.rc_mat_mul(n, a.ctypes.data, a.ctypes.data, plain.ctypes.data, ctypes.c_int(1))
    assert sized.tobytes() == plain.tobytes()


def test_runs_repeat_bit_for_bit(fmus):
    """What an archive's re-run needs: the same sets give the same numbers, whether run
    alone, in a batch, again, or in another order, and after a failed set."""
    t, f = _pmu_event(seed=7, duration=40.0)
    sim = Simulator(fmus["FrequencyInput"])
    kw = dict(output_times=t, input_time=t, inputs={"f_dev": f}, outputs=["pm"], runner="exponential")
    values = np.array([[0.05, 2.0, 1.0], [0.03, 0.2, 0.62], [0.08, 8.0, 1.0]])
    names = ["gov.R", "gov.Ts", "gov.pmax"]
    batch = sim.simulate_batch(names, values, **kw).values
    again = sim.simulate_batch(names, values[::-1], **kw).values[::-1]
    np.testing.assert_array_equal(batch, again)
    for i, row in enumerate(values):
        np.testing.assert_array_equal(sim.simulate(dict(zip(names, row)), **kw)["pm"], batch[i, :, 0])
    fresh = Simulator(fmus["FrequencyInput"]).simulate_batch(names, values, **kw).values
    np.testing.assert_array_equal(fresh, batch)


def test_the_runner_is_listed_and_the_others_unchanged(fmus):
    from rapid_cosim.simulator import RUNNERS

    assert RUNNERS[:2] == ("compiled", "python") and "exponential" in RUNNERS
    sim = Simulator(fmus["StagedTest"])
    params = {"gov.Ts": 2.0}
    compiled = sim.simulate(params, stop_time=30.0, output_interval=0.05, runner="compiled")
    python = sim.simulate(params, stop_time=30.0, output_interval=0.05, runner="python")
    assert np.max(np.abs(compiled["pm"] - python["pm"])) < 1e-12


def test_a_closed_runner_is_refused(fmus):
    sim = Simulator(fmus["StagedTest"])
    prepared = sim.prepare(["gov.Ts"], stop_time=5.0, output_interval=0.1, runner="exponential")
    sim.close()
    with pytest.raises(SimulationError, match="closed"):
        prepared.run(np.array([[1.0]]))
