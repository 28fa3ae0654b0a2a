"""The conformance suite: our own C FMUs (``tests/fmus``) in every kind (FMI 2.0 / 3.0 x
Model Exchange / Co-Simulation), each run by rapid-cosim and compared with fmpy and with an
analytic or scipy solution.

What each model covers: DroopPlant (the droop plant twin: a Real input, a tunable
first-order lag with a closed form), BouncingBall (state events, Integer and Boolean
outputs), Counter (time events, Integer and Boolean outputs, a String and, in FMI 3.0, a
Binary output, a terminate request at ``stop_at``). Co-Simulation FMUs carry their own
solver (classic Runge-Kutta at 0.01 s, events located inside the step), Model Exchange
ones run in rapid-cosim's integrators: both must meet the same references.
"""

from __future__ import annotations

import re
import warnings
import zipfile

import fmpy
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rapid_cosim.errors import ParameterError, SimulationError
from rapid_cosim.simulator import Simulator
from rapid_cosim.simulator.compiled import OK, TERMINATED, TIMEOUT
from rapid_cosim.simulator.simulation import ModelTerminated, OutputsSkipped

from c_fmus import KINDS, build_kind

CS_KINDS = [k for k in KINDS if KINDS[k][1] == "CS"]
G, E, H0 = 9.81, 0.7, 1.0  # BouncingBall's defaults
R, T, P_REF = 0.05, 2.0, 0.6  # DroopPlant's defaults


@pytest.fixture(scope="module")
def kinds(tmp_path_factory):
    """Every model in every kind, and the Co-Simulation variants: inputs held (no
    interpolation declared) and a fixed communication step."""
    folder = tmp_path_factory.mktemp("kinds")
    fmus = {(name, kind): build_kind(name, folder, kind) for kind in KINDS
            for name in ("DroopPlant", "BouncingBall", "Counter")}
    for kind in CS_KINDS:
        fmus["DroopPlant", kind, "hold"] = build_kind("DroopPlant", folder, kind, interpolate=False)
        fmus["DroopPlant", kind, "fixed"] = build_kind("DroopPlant", folder, kind, variable_step=False)
    return fmus


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OutputsSkipped)
        return fn(*args, **kw)


# --------------------------------------------------------------------------- paths


@pytest.mark.parametrize("kind", KINDS)
def test_each_kind_runs_through_its_own_path(kinds, kind):
    version, interface = KINDS[kind]
    sim = Simulator(kinds["DroopPlant", kind])
    assert sim.kind == f"FMI {version} {'Model Exchange' if interface == 'ME' else 'Co-Simulation'}"
    expected = "C driver" if interface == "CS" else "exponential runner"
    assert sim.run_path() == f"{sim.kind}, {expected}"
    if interface == "CS":
        assert sim.run_path("python") == f"{sim.kind}, fmpy loop"


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_an_fmu_with_both_interfaces_runs_model_exchange_unless_asked(version, tmp_path):
    from c_fmus import build_c_fmu
    from rapid_cosim.errors import FmuError

    both = build_c_fmu("DroopPlant", tmp_path, fmi_version=version, model_exchange=True, co_simulation=True)
    inputs = dict(output_times=np.linspace(0.0, 5.0, 51), input_time=np.array([0.0, 1.0, 1.0, 5.0]),
                  inputs={"dw": np.array([0.0, 0.0, 0.01, 0.01])})
    me, cs = Simulator(both), Simulator(both, interface="CoSimulation")
    assert me.kind == f"FMI {version} Model Exchange" and cs.kind == f"FMI {version} Co-Simulation"
    assert np.max(np.abs(me.simulate({}, **inputs)["p"] - cs.simulate({}, **inputs)["p"])) < 1e-9
    only_me = build_c_fmu("DroopPlant", tmp_path, fmi_version=version)
    with pytest.raises(FmuError, match="no Co-Simulation interface; the FMU offers Model Exchange"):
        Simulator(only_me, interface="CoSimulation")


# --------------------------------------------------------------------------- the droop plant twin


def _sine_input(t_end=20.0, dt=0.05):
    t = np.arange(0.0, t_end + 1e-9, dt)
    return t, 0.01 * np.sin(0.8 * t) + 0.004 * (t > 5.0)


def _scipy_droop(t_out, t_in, u, hold=False):
    """p' = (p_ref - u/R - p) / T with u linear between the table's rows (or held from
    each row), solved tightly, piece by piece so that steps of u are exact."""
    p0 = P_REF - u[0] / R
    out, p = [p0], p0
    for k in range(t_in.size - 1):
        a, b = t_in[k], t_in[k + 1]
        ua, ub = u[k], (u[k] if hold else u[k + 1])
        f = (lambda s, y, a=a, b=b, ua=ua, ub=ub: [(P_REF - (ua + (ub - ua) * (s - a) / (b - a)) / R - y[0]) / T])
        sol = solve_ivp(f, (a, b), [p], rtol=1e-12, atol=1e-14)
        p = sol.y[0, -1]
        out.append(p)
    return np.interp(t_out, t_in, np.array(out))


@pytest.mark.parametrize("kind", KINDS)
def test_droop_twin_follows_its_measured_input_as_scipy_does(kinds, kind):
    """Inputs linear between their samples (Model Exchange, and Co-Simulation FMUs that
    interpolate: FMI 2.0 input derivatives, FMI 3.0 intermediate update)."""
    t_in, u = _sine_input()
    sim = Simulator(kinds["DroopPlant", kind])
    traj = sim.simulate({}, output_times=t_in, input_time=t_in, inputs={"dw": u})
    expected = _scipy_droop(t_in, t_in, u)
    assert np.max(np.abs(traj["p"] - expected)) < 2e-7
    assert np.ptp(traj["p"]) > 0.2


@pytest.mark.parametrize("kind", CS_KINDS)
def test_inputs_are_held_where_the_fmu_cannot_interpolate_them(kinds, kind):
    t_in, u = _sine_input()
    traj = Simulator(kinds["DroopPlant", kind, "hold"]).simulate({}, output_times=t_in, input_time=t_in,
                                                                  inputs={"dw": u})
    held = _scipy_droop(t_in, t_in, u, hold=True)
    linear = _scipy_droop(t_in, t_in, u)
    assert np.max(np.abs(traj["p"] - held)) < 2e-7
    assert np.max(np.abs(traj["p"] - linear)) > 1e-4  # the difference is real


@pytest.mark.parametrize("kind", KINDS)
def test_droop_twin_meets_its_closed_form_and_fmpy_on_input_steps(kinds, kind):
    """Steps of the input (rows written twice): exact in every kind, as in fmpy (whose
    Model Exchange inputs are held between communication points, so that only steps
    compare; it writes the step times twice, the last row is the one after the step)."""
    t_in = np.array([0.0, 1.0, 1.0, 4.0, 4.0, 10.0])
    u = np.array([0.0, 0.0, 0.01, 0.01, -0.005, -0.005])
    t = np.arange(0.0, 10.0 + 1e-9, 0.05)
    exact = P_REF - 0.01 / R * (1 - np.exp(-(t - 1).clip(0) / T)) + 0.015 / R * (1 - np.exp(-(t - 4).clip(0) / T))
    traj = Simulator(kinds["DroopPlant", kind], relative_tolerance=1e-8).simulate(
        {}, output_times=t, input_time=t_in, inputs={"dw": u})
    assert np.max(np.abs(traj["p"] - exact)) < 1e-9
    signal = np.array(list(zip(t_in, u)), dtype=[("time", float), ("dw", float)])
    ref = fmpy.simulate_fmu(str(kinds["DroopPlant", kind]), stop_time=10.0, output_interval=0.05, input=signal,
                            relative_tolerance=1e-9)
    last = np.r_[np.diff(ref["time"]) > 0, True]
    assert np.array_equal(ref["time"][last], t)
    assert np.max(np.abs(traj["p"] - ref["p"][last])) < 1e-7


@pytest.mark.parametrize("kind", CS_KINDS)
def test_the_c_driver_and_the_fmpy_loop_agree_bit_for_bit(kinds, kind):
    t_in, u = _sine_input(8.0)
    t_out = np.sort(np.random.default_rng(3).uniform(0.0, 8.0, 90))
    for key in (("DroopPlant", kind), ("DroopPlant", kind, "hold"), ("DroopPlant", kind, "fixed")):
        sim = Simulator(kinds[key])
        values = np.array([[0.05, 2.0], [0.03, 0.7], [0.1, 5.0]])
        c = sim.simulate_batch(["R", "T"], values, output_times=t_out, input_time=t_in, inputs={"dw": u})
        py = sim.simulate_batch(["R", "T"], values, output_times=t_out, input_time=t_in, inputs={"dw": u},
                                runner="python")
        assert np.all(c.ok) and np.array_equal(c.values, py.values), key


# --------------------------------------------------------------------------- communication step


@pytest.mark.parametrize("kind", CS_KINDS)
def test_a_fixed_step_fmu_is_driven_on_its_grid_and_read_between(kinds, kind):
    """Without canHandleVariableCommunicationStepSize the step is the output interval, or
    the one given; outputs off that grid are interpolated between the points around them."""
    sim = Simulator(kinds["DroopPlant", kind, "fixed"])
    t = np.linspace(0.0, 6.0, 61)
    step = P_REF - 0.01 / R * (1 - np.exp(-(t - 1.0).clip(0) / T))
    inputs = dict(input_time=np.array([0.0, 1.0, 1.0, 6.0]), inputs={"dw": np.array([0.0, 0.0, 0.01, 0.01])})
    on_grid = sim.simulate({}, output_times=t, **inputs)
    assert np.max(np.abs(on_grid["p"] - step)) < 1e-9
    coarse = sim.simulate({}, output_times=t, communication_step=0.25, **inputs)
    on = np.isclose((t / 0.25) % 1.0, 0.0) | np.isclose((t / 0.25) % 1.0, 1.0)
    assert np.max(np.abs(coarse["p"][on] - step[on])) < 1e-9
    assert 1e-6 < np.max(np.abs(coarse["p"][~on] - step[~on])) < 2e-3  # linear between points
    with pytest.raises(SimulationError, match="communication_step must be a positive number"):
        sim.simulate({}, output_times=t, communication_step=0.0, **inputs)


@pytest.mark.parametrize("kind", CS_KINDS)
def test_a_smaller_communication_step_splits_the_intervals(kinds, kind):
    from rapid_cosim.simulator.communication import plan_communication

    sim = Simulator(kinds["DroopPlant", kind])
    t = np.linspace(0.0, 2.0, 5)
    assert plan_communication(sim.fmu, t, 0.0, None).comm.size == 5
    plan = plan_communication(sim.fmu, t, 0.0, None, communication_step=0.1)
    np.testing.assert_allclose(np.diff(plan.comm), 0.1, rtol=1e-12)
    inputs = dict(input_time=np.array([0.0, 2.0]), inputs={"dw": np.array([0.0, 0.01])})
    a = sim.simulate({}, output_times=t, communication_step=0.1, **inputs)
    b = sim.simulate({}, output_times=t, **inputs)
    assert 0 < np.max(np.abs(a["p"] - b["p"])) < 1e-10  # the FMU's own steps, split differently


# --------------------------------------------------------------------------- events


def _analytic_ball(t):
    bounce, v = [np.sqrt(2 * H0 / G)], [G * np.sqrt(2 * H0 / G)]
    while E * v[-1] >= 0.1:  # the model rests once a bounce leaves less than 0.1 m/s
        v.append(E * v[-1])
        bounce.append(bounce[-1] + 2 * v[-1] / G)
    h = np.zeros_like(t)
    for i, tt in enumerate(t):
        if tt < bounce[0]:
            h[i] = H0 - 0.5 * G * tt ** 2
            continue
        k = np.searchsorted(bounce, tt, side="right") - 1
        s = tt - bounce[k]
        h[i] = 0.0 if k == len(bounce) - 1 else v[k + 1] * s - 0.5 * G * s ** 2
    return h, np.array(bounce)


@pytest.mark.parametrize("kind", KINDS)
def test_state_events_bounce_where_the_analytic_ball_does(kinds, kind):
    t = np.linspace(0.0, 4.0, 4001)
    traj = Simulator(kinds["BouncingBall", kind]).simulate({}, output_times=t)
    h, bounce = _analytic_ball(t)
    assert np.max(np.abs(traj["h"] - h)) < 1e-4
    jumps = t[np.flatnonzero(np.diff(traj["bounces"]) > 0) + 1]
    assert len(jumps) == len(bounce) and np.max(np.abs(jumps - bounce)) <= 1e-3 + 1e-9
    assert set(np.unique(traj["falling"])) == {0.0, 1.0} and traj["resting"][-1] == 1.0
    ref = fmpy.simulate_fmu(str(kinds["BouncingBall", kind]), stop_time=4.0, output_interval=0.05,
                            relative_tolerance=1e-8)
    last = np.r_[np.diff(ref["time"]) > 0, True]  # fmpy writes event times twice
    ours = Simulator(kinds["BouncingBall", kind]).simulate({}, output_times=ref["time"][last])
    assert np.max(np.abs(ours["h"] - ref["h"][last])) < 1e-4
    assert np.array_equal(ours["bounces"], ref["bounces"][last].astype(float))


@pytest.mark.parametrize("kind", KINDS)
def test_time_events_with_integer_and_boolean_outputs(kinds, kind):
    """count = floor(t / period), odd = count % 2, x' = count: exact, as fmpy's."""
    t = np.linspace(0.0, 5.0, 101)
    traj = _quiet(Simulator(kinds["Counter", kind]).simulate, {"period": 0.7}, output_times=t)
    k = np.floor(t / 0.7 + 1e-9)
    np.testing.assert_array_equal(traj["count"], k)
    np.testing.assert_array_equal(traj["odd"], k % 2)
    np.testing.assert_allclose(traj["x"], 0.7 * k * (k - 1) / 2 + k * (t - 0.7 * k), atol=1e-9)
    ref = fmpy.simulate_fmu(str(kinds["Counter", kind]), stop_time=5.0, output_interval=0.05,
                            start_values={"period": 0.7}, output=["x", "count", "odd"])
    keep = ~np.isclose(ref["time"] / 0.7 % 1.0, 0.0) & ~np.isclose(ref["time"] / 0.7 % 1.0, 1.0)
    keep &= np.r_[True, np.diff(ref["time"]) > 0]  # fmpy writes event times twice
    _, first = np.unique(ref["time"][keep], return_index=True)
    ours = _quiet(Simulator(kinds["Counter", kind]).simulate, {"period": 0.7}, output_times=ref["time"][keep][first])
    np.testing.assert_array_equal(ours["count"], ref["count"][keep][first])
    np.testing.assert_allclose(ours["x"], ref["x"][keep][first], atol=1e-9)


# --------------------------------------------------------------------------- FMI semantics


@pytest.mark.parametrize("kind", KINDS)
def test_a_self_terminating_fmu_returns_its_trajectory_up_to_its_stop(kinds, kind):
    sim = Simulator(kinds["Counter", kind])
    with pytest.warns(ModelTerminated, match=r"terminate the simulation at t=9 s.*ends at t=9 s \(19 of 21"):
        traj = _quiet(sim.simulate, {"stop_at": 9.0}, stop_time=10.0, output_interval=0.5)
    assert traj.time[-1] == 9.0 and traj["count"][-1] == 9.0 and traj["x"][-1] == pytest.approx(36.0)
    ref = fmpy.simulate_fmu(str(kinds["Counter", kind]), stop_time=10.0, output_interval=0.5,
                            start_values={"stop_at": 9.0}, output=["x", "count"])
    assert ref["x"][-1] == pytest.approx(traj["x"][-1])  # fmpy too stops at t = 9 s
    with pytest.warns(ModelTerminated, match=r"at t=7.2 s.*ends at t=7 s"):
        between = _quiet(sim.simulate, {"stop_at": 7.2}, stop_time=10.0, output_interval=0.5)
    assert between.time[-1] == 7.0


@pytest.mark.parametrize("kind", KINDS)
def test_a_terminated_set_is_a_failure_of_its_batch(kinds, kind):
    sim = Simulator(kinds["Counter", kind])
    batch = _quiet(sim.simulate_batch, ["stop_at"], np.array([[3.2], [20.0], [10.0]]), stop_time=10.0,
                   output_interval=0.5, outputs=["x", "count"])
    assert batch.status.tolist() == [TERMINATED, OK, OK]  # stopping at the last output time gave it all
    assert "asked to terminate at t=3.2" in batch.messages[0]
    assert np.all(np.isfinite(batch.values[0, :7])) and np.all(np.isnan(batch.values[0, 7:]))
    np.testing.assert_array_equal(batch.values[1], batch.values[2])


@pytest.mark.parametrize("kind", KINDS)
def test_outputs_that_are_not_numbers_are_skipped_with_a_note(kinds, kind):
    sim = Simulator(kinds["Counter", kind])
    skipped = "label (String), raw (Binary)" if KINDS[kind][0] == "3.0" else "label (String)"
    with pytest.warns(OutputsSkipped, match=rf"output\(s\) {re.escape(skipped)} are not numbers"):
        traj = sim.simulate({}, stop_time=2.0, output_interval=0.5)
    assert list(traj.outputs) == ["x", "count", "odd"]
    with pytest.raises(ParameterError, match=r"cannot record label \(String\)"):
        sim.simulate({}, stop_time=2.0, output_interval=0.5, outputs=["x", "label"])


@pytest.mark.parametrize("kind", CS_KINDS)
def test_a_co_simulation_set_over_its_budget_times_out_and_the_next_runs(kinds, kind):
    sim = Simulator(kinds["BouncingBall", kind], timeout=1e-9)
    batch = sim.simulate_batch(["e"], np.array([[0.7], [0.6]]), stop_time=5.0, output_interval=0.01)
    assert batch.status.tolist() == [TIMEOUT, TIMEOUT] and "wall-clock budget" in batch.messages[0]
    sim.timeout = None
    again = sim.simulate_batch(["e"], np.array([[0.7], [0.6]]), stop_time=5.0, output_interval=0.01)
    assert np.all(again.ok)



@pytest.mark.parametrize("runner", ["exponential", "compiled", "python"])
@pytest.mark.parametrize("kind", ["me3", "cs3"])
def test_fmi3_instances_keep_the_standards_state_machine(kinds, kind, runner):
    """The FMI 3.0 test FMUs check the state machine as strictly as the standard's Reference
    FMUs (an illegal call fails: "Illegal call sequence"; tests/fmus/fmu_fmi3.h): a fresh
    instance's first set, sets on the reset instance, a set after one the model terminated
    and after a failed one, on every runner."""
    grid = dict(stop_time=5.0, output_interval=0.5, outputs=["x", "count"], runner=runner)
    sim = Simulator(kinds["Counter", kind])
    sets = np.array([[1e9], [3.2], [1e9]])
    batch = _quiet(sim.simulate_batch, ["stop_at"], sets, **grid)
    assert batch.status.tolist() == [OK, TERMINATED, OK], batch.messages
    np.testing.assert_array_equal(batch.values[2], batch.values[0])
    sim.timeout = 1e-12  # a failed set: over its budget (200 steps: the exponential runner looks every 64)
    failed = _quiet(sim.simulate_batch, ["stop_at"], sets[:1], **{**grid, "output_interval": 0.025})
    assert failed.status.tolist() == [TIMEOUT]
    sim.timeout = None
    again = _quiet(sim.simulate_batch, ["stop_at"], sets, **grid)
    assert again.status.tolist() == [OK, TERMINATED, OK] and not any("Illegal" in m for m in again.messages)
    np.testing.assert_array_equal(again.values[0], batch.values[0])


# --------------------------------------------------------------------------- inputs not given


@pytest.mark.parametrize("kind", KINDS)
def test_inputs_not_given_are_held_at_their_start_values_with_a_note(kinds, kind):
    """As fmpy holds them: the droop twin's dw at its start 0 leaves p at p_ref; the note
    names the input and the value, once per simulator."""
    from rapid_cosim.simulator.simulation import InputsHeld

    sim = Simulator(kinds["DroopPlant", kind])
    with pytest.warns(InputsHeld, match=r"DroopPlant: input\(s\) not given are held at their start values: dw = 0"):
        traj = sim.simulate({}, stop_time=5.0, output_interval=0.5)
    np.testing.assert_allclose(traj["p"], P_REF, atol=1e-12)
    assert sim.prepare([], stop_time=5.0, output_interval=0.5).held_inputs == {"dw": "0.0"}
    with warnings.catch_warnings():
        warnings.simplefilter("error", InputsHeld)  # noted once
        batch = sim.simulate_batch(["p_ref"], np.array([[0.5], [0.7]]), stop_time=5.0, output_interval=0.5)
    np.testing.assert_allclose(batch.values[:, :, 0], [[0.5] * 11, [0.7] * 11], atol=1e-12)
    ref = fmpy.simulate_fmu(str(kinds["DroopPlant", kind]), stop_time=5.0, output_interval=0.5)
    np.testing.assert_allclose(ref["p"], P_REF, atol=1e-12)


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_an_input_without_a_start_value_must_be_given(version, tmp_path):
    from c_fmus import build_c_fmu

    fmu = build_c_fmu("DroopPlant", tmp_path, fmi_version=version)
    with zipfile.ZipFile(fmu) as zf:
        files = {n: zf.read(n) for n in zf.namelist()}
    xml = files["modelDescription.xml"].decode()
    files["modelDescription.xml"] = (re.sub(r'(name="dw"[^>]*?) start="0.0"', r"\1", xml) if version == "3.0"
                                     else xml.replace('<Real start="0.0"/></ScalarVariable>',
                                                      "<Real/></ScalarVariable>")).encode()
    assert files["modelDescription.xml"] != xml.encode()
    unset = tmp_path / "unset.fmu"
    with zipfile.ZipFile(unset, "w") as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    with pytest.raises(ParameterError, match="DroopPlant has inputs dw; dw has no start value to hold: give it values"):
        Simulator(unset).simulate({}, stop_time=1.0, output_interval=0.5)


def test_an_fmu_with_clocks_is_refused_naming_them(kinds, tmp_path):
    """FMI 3.0 clocks need event handling by clock (and a Scheduled Execution FMU its
    partitions activated by them): refused by name rather than run wrong."""
    from rapid_cosim.errors import FmuError

    with zipfile.ZipFile(kinds["Counter", "me3"]) as zf:
        files = {n: zf.read(n) for n in zf.namelist()}
    xml = files["modelDescription.xml"].decode()
    clock = '    <Clock name="tick" valueReference="500" causality="input" variability="discrete"/>\n'
    files["modelDescription.xml"] = xml.replace("  </ModelVariables>", clock + "  </ModelVariables>").encode()
    clocked = tmp_path / "clocked.fmu"
    with zipfile.ZipFile(clocked, "w") as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    with pytest.raises(FmuError, match=r"FMI 3.0 clocks \(tick\) need event handling by clock"):
        Simulator(clocked)


def test_a_dead_process_extracted_fmus_are_removed_by_the_next_load(kinds, tmp_path, monkeypatch):
    """An extracted FMU's folder is named by its process; a worker killed mid-run never
    removes its own (a fleet's killed workers left hundreds in /tmp), so the next load
    removes those whose process is gone, and keeps a live one's and foreign folders."""
    import os
    import subprocess
    import sys
    import tempfile

    from rapid_cosim.simulator.fmu import EXTRACTED, LoadedFmu

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead, live, other = (tmp_path / f"{EXTRACTED}{gone.stdout.strip()}_abc", tmp_path / f"{EXTRACTED}{1}_abc",
                         tmp_path / "rapid_cosim_fmu_old")
    for folder in (dead, live, other):
        (folder / "binaries").mkdir(parents=True)
    loaded = LoadedFmu(kinds["DroopPlant", next(iter(KINDS))])
    assert not dead.exists() and live.exists() and other.exists()  # pid 1 lives as long as the machine
    assert loaded.dir.parent == tmp_path and loaded.dir.name.startswith(f"{EXTRACTED}{os.getpid()}_")
