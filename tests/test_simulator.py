"""The simulator: parameter checks, instance reuse, typed failures."""

import numpy as np
import pytest

from rapid_cosim.errors import ParameterError, SimulationError, SimulationTimeout
from rapid_cosim.simulator import Simulator, get_simulator

@pytest.fixture(scope="module")
def staged(fmus):
    return Simulator(fmus["StagedTest"])


def test_unknown_parameter_name_suggests_close_ones(staged):
    with pytest.raises(ParameterError, match=r"no parameter 'gov\.Rr'.*gov\.R"):
        staged.simulate({"gov.Rr": 0.05}, stop_time=1, output_interval=0.1)


def test_value_outside_declared_range_names_the_range(staged):
    with pytest.raises(ParameterError, match=r"gov\.Ts = 200 is outside its declared range \[0\.001, 100\]"):
        staged.simulate({"gov.Ts": 200.0}, stop_time=1, output_interval=0.1)


def test_calculated_parameter_cannot_be_set(fmus):
    sim = Simulator(fmus["StagedTestDeadband"])
    with pytest.raises(ParameterError, match="calculated"):
        sim.simulate({"db.d": 0.001}, stop_time=1, output_interval=0.1)


def test_reuse_gives_identical_runs_and_p_ref_reinitialises(staged):
    a = staged.simulate({"gov.p_ref": 0.7, "gov.Ts": 2.0}, stop_time=30, output_interval=0.05)
    staged.simulate({"gov.p_ref": 0.3, "gov.Ts": 9.0}, stop_time=30, output_interval=0.05)
    b = staged.simulate({"gov.p_ref": 0.7, "gov.Ts": 2.0}, stop_time=30, output_interval=0.05)
    assert np.array_equal(a["pm"], b["pm"])
    assert a["pm"][0] == pytest.approx(0.7, abs=1e-12)  # steady start follows p_ref set at run time


def test_a_repeated_grid_reuses_its_prepared_batch_and_results_stay_apart(fmus):
    sim = Simulator(fmus["StagedTest"])
    grid = dict(stop_time=30, output_interval=0.05)
    a = sim.simulate({"gov.Ts": 2.0}, **grid)
    assert len(sim._batches) == 1
    b = sim.simulate({"gov.Ts": 9.0}, **grid)
    assert len(sim._batches) == 1 and not np.array_equal(a["pm"], b["pm"])  # one batch, separate results
    fresh = sim.prepare(["gov.Ts"], **grid).run(np.array([[2.0]])).trajectory(0)
    assert np.array_equal(sim.simulate({"gov.Ts": 2.0}, **grid)["pm"], fresh["pm"])
    c = sim.simulate({"gov.Ts": 2.0}, stop_time=20, output_interval=0.05)
    assert c.time[-1] == pytest.approx(20) and len(sim._batches) == 2
    with pytest.raises(ValueError):  # the shared time base cannot be changed through a result
        a.time[0] = 1.0


def test_a_recorded_input_is_remembered_by_content_not_by_identity(fmus):
    sim = Simulator(fmus["FrequencyInput"])
    t = np.linspace(0.0, 20.0, 401)
    f_dev = np.where(t > 5.0, -0.1, 0.0)
    a = sim.simulate({}, output_times=t, input_time=t, inputs={"f_dev": f_dev})
    b = sim.simulate({}, output_times=t.copy(), input_time=t.copy(), inputs={"f_dev": f_dev.copy()})
    assert len(sim._batches) == 1 and np.array_equal(a["pm"], b["pm"])
    f_dev[t > 10.0] = -0.2  # the same array changed in place: a new batch, a new answer
    c = sim.simulate({}, output_times=t, input_time=t, inputs={"f_dev": f_dev})
    assert len(sim._batches) == 2 and c["pm"][-1] > a["pm"][-1] + 0.5 * 0.1 / 50 / 0.05


def test_trajectory_covers_a_stop_time_off_the_grid(staged):
    traj = staged.simulate({}, stop_time=10.03, output_interval=0.05)
    assert traj.time[-1] >= 10.03 and np.allclose(np.diff(traj.time), 0.05)


def test_solver_failure_is_a_typed_error_and_the_simulator_recovers(blowup):
    with pytest.raises(SimulationError, match="Blowup failed"):
        blowup.simulate({"a": 1.0}, stop_time=2.0, output_interval=0.1, outputs=["x"])
    ok = blowup.simulate({"a": 0.1}, stop_time=2.0, output_interval=0.1, outputs=["x"])
    assert ok["x"][-1] == pytest.approx(1 / (1 - 0.1 * 2.0), rel=1e-4)


def test_timeout_is_a_typed_error(fmus):
    sim = Simulator(fmus["StagedTest"], timeout=1e-9)
    with pytest.raises(SimulationTimeout, match="time-out"):
        sim.simulate({}, stop_time=60, output_interval=0.05)


def test_process_cache_returns_one_simulator_per_fmu(fmus):
    assert get_simulator(fmus["StagedTest"]) is get_simulator(fmus["StagedTest"])


def test_output_times_match_the_grid_and_fmpys_own_loop(staged, fmus):
    """CVODE's path (the compiled runner) takes the steps fmpy's own loop takes."""
    import fmpy

    params = {"gov.Ts": 2.0, "src.t_return": 30.0}
    grid = staged.simulate(params, stop_time=40, output_interval=0.05, runner="compiled")
    picked = grid.time[[3, 200, 201, 650, 799]] + np.array([0.0, 0.0, 0.013, 0.0, 0.0])
    at = staged.simulate(params, output_times=picked, runner="compiled")
    assert np.array_equal(at.time, picked)
    same = [0, 1, 3, 4]
    # other output points make CVode take other steps: equal to solver tolerance, not bits
    assert np.max(np.abs(at["pm"][same] - grid["pm"][[3, 200, 650, 799]])) < 1e-6
    reference = fmpy.simulate_fmu(str(fmus["StagedTest"]), stop_time=40, output_interval=0.05, start_values=params,
                                  record_events=False, output=["pm"], relative_tolerance=1e-6)
    assert np.max(np.abs(reference["pm"] - grid["pm"])) < 1e-9


def test_values_at_an_event_are_those_after_it(staged):
    traj = staged.simulate({"src.t_step": 10.0}, output_times=np.array([9.99, 10.0]), outputs=["gov.pin"])
    assert traj["gov.pin"][0] == pytest.approx(0.6) and traj["gov.pin"][1] == pytest.approx(0.68)
