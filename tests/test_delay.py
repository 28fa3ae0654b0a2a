"""The exact transport delay (issue 55): the recorded-frequency bench's governor reads the
recording at t - dly.T (``rapid_cosim.simulator.delayed``), a staged test's step arrives
dly.T late (``Sources.FrequencyStep.t_delay``). Checked against an integration of TG Type I
(eqs. 1-6) with a true delay, written apart from the models (``reference_models``): on a
step (``test_reference.py``'s StagedTestDelay cases), a ramp and a recorded event."""

import shutil

import numpy as np
import pytest
from reference_models import Reference, integrate_between_switches

from rapid_cosim.compiler import build_models
from rapid_cosim.diagnose.catalogue import INPUT_BENCH, write_bench
from rapid_cosim.experiment import load_experiment
from rapid_cosim.simulator import InputTable, Simulator
from rapid_cosim.simulator.delayed import DELAYED_FREQUENCY, delayed_table, with_delayed

F_NOM = 50.0
GOV = {"gov.R": 0.05, "gov.Ts": 0.8, "gov.Tc": 0.4, "gov.T3": 0.2, "gov.T4": 1.5, "gov.T5": 6.0, "gov.p_ref": 0.6}


def test_a_delayed_table_is_the_recording_moved_with_its_steps():
    table = with_delayed(InputTable(np.array([0.0, 10.0, 10.0, 20.0]), ("f_dev",), np.array([0.0, 0.0, -0.2, -0.1])))
    moved = delayed_table(table, 0.75)
    t, f, d = moved.time, moved.values[:, 0], moved.values[:, 1]
    assert DELAYED_FREQUENCY in moved.names
    assert list(t) == [0.0, 0.75, 10.0, 10.0, 10.75, 10.75, 20.0, 20.75]  # each step written twice, moved too
    np.testing.assert_allclose(f, [0, 0, 0, -0.2, -0.2 + 0.1 * 0.075, -0.2 + 0.1 * 0.075, -0.1, -0.1])
    np.testing.assert_allclose(d, [0, 0, 0, 0, 0, -0.2, -0.2 + 0.1 * 0.925, -0.1])
    assert np.array_equal(delayed_table(table, 0.0).values[:, 1], delayed_table(table, 0.0).values[:, 0])
    with pytest.raises(Exception, match="not negative"):
        delayed_table(table, -0.1)


@pytest.fixture(scope="module")
def delayed_bench(repo, tmp_path_factory):
    """The discrepancy workflow's recorded-frequency bench with a delay, as it writes it."""
    root = tmp_path_factory.mktemp("delay")
    package = root / "iGrGen"
    shutil.copytree(repo / "modelica" / "iGrGen", package)
    write_bench(package, ["delay"], "iGrGen.Diagnosed.FrequencyInputDelay", base=INPUT_BENCH,
                values={"f_nom": F_NOM})
    built = build_models(["iGrGen.Diagnosed.FrequencyInputDelay"], package=package, fmu_dir=root / "fmus",
                         log=lambda *_: None)
    return Simulator(built[0].fmu)


class _Recorded(Reference):
    """TG Type I fed the recorded deviation ``f`` (Hz) at t - T, as the plant's governor hears it."""

    def __init__(self, time, f, delay):
        super().__init__("StagedTest", GOV)
        self.time, self.f, self.delay = time, f, delay

    def dw(self, t):
        return -np.interp(t - self.delay, self.time, self.f) / F_NOM


def _compare(sim, time, f, delay):
    t_out = np.arange(0.0, time[-1], 0.05)
    got = sim.simulate({**GOV, "dly.T": delay}, output_times=t_out, input_time=time, inputs={"f_dev": f},
                       outputs=["pm"])["pm"]
    ref = _Recorded(time, f, delay)
    p = {"src.t_step": float(time[1]) + delay, "src.t_return": 1e9}  # the ramp's corner, moved: cut there
    expected = integrate_between_switches(ref.rhs, ref.output, ref.steady_start(), p, t_out)
    return np.max(np.abs(got - expected)), np.ptp(expected)


@pytest.mark.parametrize("delay", [0.3, 1.7])
def test_the_delay_on_a_ramp_matches_an_integration_with_a_true_delay(delayed_bench, delay):
    time = np.array([0.0, 5.0, 9.0, 40.0])
    f = np.array([0.0, 0.0, -0.2, -0.2])  # a 50 mHz/s ramp to -200 mHz, held
    worst, moved = _compare(delayed_bench, time, f, delay)
    print(f"delay {delay} s, a ramp: largest difference {worst:.1e} pu (the response moves {moved:.3f} pu)")
    assert worst < 1e-4 and moved > 0.05


def test_the_delay_on_a_recorded_event_matches_an_integration_with_a_true_delay(delayed_bench, repo):
    table = load_experiment(repo / "experiments" / "event1" / "config.toml").input_table  # a PMU's 50 frames/s
    time, f = table.time, table.values[:, table.names.index("f_dev")]
    worst, moved = _compare(delayed_bench, time, f, 0.8)
    print(f"delay 0.8 s, event1's frequency: largest difference {worst:.1e} pu (the response moves {moved:.3f} pu)")
    assert worst < 1e-4 and moved > 0.01


def test_each_set_of_a_batch_has_its_own_delay(delayed_bench):
    time = np.array([0.0, 5.0, 5.0, 30.0])
    f = np.array([0.0, 0.0, -0.2, -0.2])
    names = ["gov.Ts", "dly.T"]
    values = np.array([[0.8, 0.2], [0.8, 1.4], [2.0, 0.6]])
    batch = delayed_bench.simulate_batch(names, values, output_times=np.arange(0.0, 30.0, 0.1), input_time=time,
                                         inputs={"f_dev": f}, outputs=["pm"])
    for i, row in enumerate(values):
        alone = delayed_bench.simulate(dict(zip(names, row)), output_times=batch.time, input_time=time,
                                       inputs={"f_dev": f}, outputs=["pm"])["pm"]
        np.testing.assert_array_equal(batch.values[i, :, 0], alone)
        onset = batch.time >= 5.0 + row[1]
        np.testing.assert_allclose(batch.values[i, ~onset, 0], batch.values[i, 0, 0], atol=1e-12)  # nothing before it arrives
        assert batch.values[i, -1, 0] > batch.values[i, 0, 0] + 0.05  # then the governor opens


def test_fmpy_runs_the_delayed_bench_as_the_compiled_runner_does(delayed_bench):
    """The delayed bench's FMU read by another program (fmpy's own loop, runner "python")
    through the path a user takes: each set's delayed recording, a step among them, gives
    the compiled runner's response."""
    time = np.array([0.0, 5.0, 5.0, 30.0])
    f = np.array([0.0, 0.0, -0.2, -0.2])
    values = np.array([[0.8, 0.2], [2.0, 1.4]])
    kwargs = dict(output_times=np.arange(0.0, 30.0, 0.1), input_time=time, inputs={"f_dev": f}, outputs=["pm"])
    ours = delayed_bench.simulate_batch(["gov.Ts", "dly.T"], values, runner="compiled", **kwargs)
    fmpy = delayed_bench.simulate_batch(["gov.Ts", "dly.T"], values, runner="python", **kwargs)
    assert fmpy.ok.all() and np.max(np.abs(fmpy.values - ours.values)) < 1e-4
    assert np.ptp(ours.values[:, :, 0], axis=1).min() > 0.05
