"""The compiled batch runner: the same numbers as the Python reference loop, state events,
inputs, typed outputs, and failures that stay with their set."""

from pathlib import Path

import numpy as np
import pytest
from c_fmus import build_c_fmu
from reference_models import EFFECT_DEFAULTS, Reference
from test_reference import CASES, EFFECT_ACTIVE

from rapid_cosim.errors import FmuError, SimulationError, SimulationTimeout
from rapid_cosim.simulator import InputTable, Simulator
from rapid_cosim.simulator.compiled import TIMEOUT


@pytest.fixture(scope="module")
def c_fmus(tmp_path_factory):
    folder = tmp_path_factory.mktemp("c_fmus")
    return {name: build_c_fmu(name, folder) for name in ("BouncingBall", "Counter", "DroopPlant")}


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("bench", list(EFFECT_DEFAULTS))
def test_compiled_runner_matches_the_python_loop(fmus, bench, case):
    sim = Simulator(fmus[bench])
    params = {k: v for k, v in Reference(bench, {**CASES[case], **EFFECT_ACTIVE.get(bench, {})}).p.items()
              if sim.parameters[k].settable}
    samples = np.sort(np.random.default_rng(0).uniform(0.0, 60.0, 700))  # jittered, like a recorder
    for kw in ({"stop_time": 60.0, "output_interval": 0.05}, {"output_times": samples}):
        python = sim.simulate(params, runner="python", **kw)
        compiled = sim.simulate(params, runner="compiled", **kw)
        assert np.max(np.abs(python["pm"] - compiled["pm"])) < 1e-6
        assert np.ptp(compiled["pm"]) > 0.01


def test_a_batch_gives_each_set_what_a_single_run_gives(fmus):
    sim = Simulator(fmus["StagedTestRateLimit"])
    names = ["gov.Ts", "gov.rate_open", "src.t_return"]
    values = np.array([[0.5, 0.004, 30.0], [5.0, 0.02, 1e9], [2.0, 0.01, 45.0]])
    batch = sim.simulate_batch(names, values, stop_time=60.0, output_interval=0.1, outputs=["pm"])
    assert np.all(batch.ok)
    for i, row in enumerate(values):
        single = sim.simulate(dict(zip(names, row)), stop_time=60.0, output_interval=0.1)
        assert np.array_equal(batch.values[i, :, 0], single["pm"])


def test_bouncing_ball_bounces_where_the_analytic_solution_does(c_fmus):
    """State events: the ball, dropped from 1 m, bounces at t_k with h(t) a parabola
    between bounces; with the Python loop's blindness to event indicators it fell through
    the floor, so that loop refuses such FMUs."""
    g, e, h0 = 9.81, 0.7, 1.0
    sim = Simulator(c_fmus["BouncingBall"])
    bounce = [np.sqrt(2 * h0 / g)]
    v = [g * bounce[0]]
    while e * v[-1] >= 0.1:  # the model rests once a bounce leaves less than 0.1 m/s
        v.append(e * v[-1])
        bounce.append(bounce[-1] + 2 * v[-1] / g)
    t = np.linspace(0.0, 4.0, 4001)
    traj = sim.simulate({}, output_times=t, outputs=["h", "bounces", "falling", "resting"])

    def analytic(tt):
        if tt < bounce[0]:
            return h0 - 0.5 * g * tt ** 2
        k = np.searchsorted(bounce, tt, side="right") - 1
        if k == len(bounce) - 1:
            return 0.0
        s = tt - bounce[k]
        return v[k + 1] * s - 0.5 * g * s ** 2

    expected = np.array([analytic(tt) for tt in t])
    assert np.max(np.abs(traj["h"] - expected)) < 1e-4
    assert traj["h"].min() > -1e-6  # never through the floor
    counts = traj["bounces"]
    jumps = t[np.flatnonzero(np.diff(counts) > 0) + 1]
    assert len(jumps) == len(bounce)
    assert np.max(np.abs(jumps - np.array(bounce))) <= 1e-3 + 1e-9  # on the 1 ms output grid
    assert traj["resting"][-1] == 1.0 and traj["falling"][0] == 0.0
    with pytest.raises(FmuError, match="state events.*compiled runner"):
        sim.simulate({}, stop_time=1.0, output_interval=0.1, runner="python")


def test_integer_and_boolean_outputs_are_read_as_numbers(c_fmus):
    for runner in ("compiled", "python"):
        traj = Simulator(c_fmus["Counter"]).simulate({"period": 0.5}, stop_time=2.2, output_interval=0.25,
                                                     outputs=["count", "odd", "x"], runner=runner)
        assert list(traj["count"]) == [0, 0, 1, 1, 2, 2, 3, 3, 4, 4]
        assert list(traj["odd"]) == [0, 0, 1, 1, 0, 0, 1, 1, 0, 0]
        # x' = count: the integral of a staircase
        assert traj["x"][-1] == pytest.approx(0.5 * (1 + 2 + 3) + 0.25 * 4, abs=1e-6)


def test_inputs_with_ramps_and_steps_match_the_analytic_response(c_fmus):
    """p' = (p_ref - dw/R - p)/T driven by a ramp then a step back: both runners follow the
    exact solution, the step taken as a time event (not smeared across a solver step)."""
    R, T, p_ref = 0.05, 2.0, 0.6
    table = InputTable.from_columns([0.0, 5.0, 10.0, 20.0, 20.0, 40.0], {"dw": [0, 0, -0.004, -0.004, 0, 0]})
    t = np.linspace(0.0, 40.0, 801)
    dense = np.linspace(0.0, 40.0, 400001)
    u = np.array([table.at(tt) for tt in dense])[:, 0]
    target = p_ref - u / R
    # exact discretisation of the lag on the fine grid (trapezoidal input between points)
    p = np.empty_like(dense)
    p[0] = p_ref
    a = np.exp(-np.diff(dense) / T)
    for k in range(dense.size - 1):
        p[k + 1] = a[k] * p[k] + (1 - a[k]) * 0.5 * (target[k] + target[k + 1])
    expected = np.interp(t, dense, p)
    for runner in ("compiled", "python"):
        traj = Simulator(c_fmus["DroopPlant"]).simulate({"R": R, "T": T}, output_times=t, inputs=table,
                                                        runner=runner)
        assert np.max(np.abs(traj["p"] - expected)) < 2e-5


def test_recorded_frequency_drives_the_bench_alike_in_both_runners(fmus):
    rng = np.random.default_rng(3)
    time = np.arange(0.0, 110.0, 0.04)  # 25 Hz, as a PMU
    nadir = -0.15 * np.clip(time - 10, 0, None) / 4 * np.exp(-np.clip(time - 10, 0, None) / 8)
    f_dev = nadir + 0.002 * rng.standard_normal(time.size)
    sim = Simulator(fmus["FrequencyInput"])
    kw = dict(output_times=time, input_time=time, inputs={"f_dev": f_dev})
    python = sim.simulate({"gov.Ts": 2.0}, runner="python", **kw)
    compiled = sim.simulate({"gov.Ts": 2.0}, runner="compiled", **kw)
    assert np.max(np.abs(python["pm"] - compiled["pm"])) < 1e-6
    assert np.ptp(compiled["pm"]) > 0.01


def test_failures_stay_with_their_set(blowup):
    batch = blowup.simulate_batch(["a"], np.array([[0.1], [1.0], [0.2], [5.0], [0.3]]), stop_time=2.0,
                                  output_interval=0.1, outputs=["x"])
    assert np.all(batch.ok[[0, 2, 4]]) and not np.any(batch.ok[[1, 3]])
    assert batch.values[4, -1, 0] == pytest.approx(1 / (1 - 0.3 * 2.0), rel=1e-4)
    assert np.all(np.isnan(batch.values[1])) and "Blowup failed with a=1" in batch.messages[1]
    with pytest.raises(SimulationError, match="Blowup failed"):
        blowup.simulate({"a": 1.0}, stop_time=2.0, output_interval=0.1, outputs=["x"])


def test_a_timed_out_set_does_not_stall_the_batch(fmus):
    sim = Simulator(fmus["StagedTest"], timeout=1e-7)
    batch = sim.simulate_batch(["gov.Ts"], np.array([[1.0], [2.0], [3.0]]), stop_time=60.0, output_interval=0.05)
    assert np.all(batch.status == TIMEOUT)
    assert all("wall-clock" in m for m in batch.messages)
    sim.timeout = None
    assert np.all(sim.simulate_batch(["gov.Ts"], np.array([[1.0]]), stop_time=60.0, output_interval=0.05).ok)
    sim.timeout = 1e-7
    with pytest.raises(SimulationTimeout, match="time-out"):
        sim.simulate({}, stop_time=60.0, output_interval=0.05)


def test_unknown_runner_is_refused(fmus):
    with pytest.raises(Exception, match="unknown runner 'fast'.*compiled, python"):
        Simulator(fmus["StagedTest"]).simulate({}, stop_time=1.0, output_interval=0.1, runner="fast")


def test_runner_library_is_cached_by_source_hash():
    from rapid_cosim.simulator.compiled import library_path

    first = library_path()
    assert first.exists() and library_path() == first
    assert Path(first).name.startswith("rapid_cosim_runner-")
