"""The FMI standard's own Reference FMUs, both FMI versions, both interfaces, as fmpy runs
them (tests/reference_fmus.py builds them from ../shared/reference-fmus once per test run).

Each is run by every runner that takes it, on a fresh instance, again on the reset one and
in a batch, and compared: Model Exchange with fmpy's at rtol 1e-10 (or with the closed
form where there is one) within 1e-6, Co-Simulation with fmpy's at the same communication
step within 1e-9. What is refused is refused with the FMI feature named. Skipped, with the
reason, where the source or cmake is absent.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

import rapid_cosim as rc
from rapid_cosim.errors import FmuError, ParameterError
from rapid_cosim.simulator import Simulator
from rapid_cosim.simulator.simulation import InputsHeld, ModelTerminated, OutputsSkipped

import reference_fmus as ref
from reference_fmus import CS, ME

ME_TOL, CS_TOL = 1e-6, 1e-9


@pytest.fixture(scope="session")
def reference():
    """(version, model) -> FMU path, both builds."""
    reason = ref.unavailable()
    if reason:
        pytest.skip(f"Reference FMUs not built: {reason}")
    return {(v, m): path for v in ref.MODELS for m, path in ref.build(v).items()}


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        for kind in (InputsHeld, OutputsSkipped, ModelTerminated):
            warnings.simplefilter("ignore", kind)
        return fn(*args, **kw)


def _runners(version: str, model: str, interface: str) -> list[str]:
    """Every runner that takes the case: the Python loop runs Model Exchange without state
    events (BouncingBall and Roberts have them), and fmpy's loop every Co-Simulation FMU."""
    if interface == CS:
        return ["exponential", "python"]  # the C driver (for "compiled" too) and the fmpy loop
    return ["exponential", "compiled"] + ([] if model in ("BouncingBall", "Roberts") else ["python"])


@pytest.mark.parametrize("version,model,interface", ref.cases(), ids=["-".join(c) for c in ref.cases()])
def test_every_reference_fmu_runs_as_fmpy_runs_it(reference, version, model, interface):
    path = reference[version, model]
    theirs = _quiet(ref.fmpy_run, path, model, interface)
    until = ref.COMPARED_UNTIL.get((model, interface), np.inf)
    for runner in _runners(version, model, interface):
        sim = Simulator(path, interface=interface, relative_tolerance=ref.RTOL)
        first = _quiet(ref.ours, sim, model, interface, runner)  # a fresh instance
        again = _quiet(ref.ours, sim, model, interface, runner)  # the same, reset
        for n in first.outputs:
            np.testing.assert_array_equal(again[n], first[n], err_msg=f"{runner}: {n} on the reset instance")
        exact = ref.closed_form(model, first.time)
        worst = ref.largest_difference(first, theirs, until)
        if interface == CS:
            assert worst <= CS_TOL, f"{runner}: {worst:.3g} from fmpy's Co-Simulation run"
        elif exact is not None:
            off = max(float(np.max(np.abs(first[n] - x) / np.maximum(1.0, np.abs(x)))) for n, x in exact.items())
            assert min(worst, off) <= ME_TOL, f"{runner}: {worst:.3g} from fmpy, {off:.3g} from the closed form"
        else:
            assert worst <= ME_TOL, f"{runner}: {worst:.3g} from fmpy's Model Exchange run"
        start, _, step = ref.experiment(model, interface)
        grid = dict(output_times=ref.grid(model, interface), start_time=start, runner=runner,
                    communication_step=step if interface == CS else None)
        batch = _quiet(sim.simulate_batch, [], np.zeros((3, 0)), **grid)
        rows = first.time.size  # Stair's sets end where it asks to terminate
        assert np.array_equal(batch.values[:, :rows], np.repeat(batch.values[:1, :rows], 3, axis=0), equal_nan=True)
        assert np.array_equal(batch.values[0, :rows], np.column_stack([first[n] for n in first.outputs]))


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_rc_simulate_runs_them_at_its_default_tolerance(reference, version):
    """The user's call of the issue: rc.simulate(path, {}, ...), Model Exchange where the
    FMU has it, CVODE's default tolerance (1e-6) for the exponential runner's fallback."""
    for (v, model), path in reference.items():
        if v != version or (v, model) in ref.REFUSED:
            continue
        start, stop, step = ref.experiment(model, ME)
        traj = _quiet(rc.simulate, path, {}, output_times=ref.grid(model, ME), outputs=None)
        theirs = _quiet(ref.fmpy_run, path, model, ME)
        assert ref.largest_difference(traj, theirs, ref.COMPARED_UNTIL.get((model, ME), np.inf)) < 2e-3, model


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_closed_forms_dahlquist_and_the_first_bounce(reference, version):
    """Dahlquist x = exp(-t) to rounding (the exponential runner is exact on a linear
    model); BouncingBall falls as h = 1 - g t^2 / 2 and first reaches the floor at
    sqrt(2 / g), leaving it at 0.7 of its speed."""
    dahlquist = Simulator(reference[version, "Dahlquist"]).simulate({}, stop_time=10.0, output_interval=0.1)
    assert np.max(np.abs(dahlquist["x"] - np.exp(-dahlquist.time))) < 1e-14
    k2 = Simulator(reference[version, "Dahlquist"]).simulate({"k": 2.0}, stop_time=5.0, output_interval=0.1)
    assert np.max(np.abs(k2["x"] - np.exp(-2.0 * k2.time))) < 1e-14
    t_hit, g = ref.first_impact(), 9.81
    t = np.sort(np.r_[np.linspace(0.0, 0.8, 81), t_hit - 1e-6, t_hit + 1e-6])
    ball = _quiet(Simulator(reference[version, "BouncingBall"], relative_tolerance=ref.RTOL).simulate, {},
                  output_times=t)
    before = t < t_hit
    np.testing.assert_allclose(ball["h"][before], 1.0 - g * t[before] ** 2 / 2, atol=ME_TOL)
    after = t > t_hit
    np.testing.assert_allclose(ball["v"][after], 0.7 * g * t_hit - g * (t[after] - t_hit), atol=ME_TOL)
    np.testing.assert_allclose(ball["h"][after], 0.7 * g * t_hit * (t[after] - t_hit) - g * (t[after] - t_hit) ** 2 / 2,
                               atol=ME_TOL)
    assert ball["v"][t == t_hit - 1e-6][0] < 0 < ball["v"][t == t_hit + 1e-6][0]


@pytest.mark.parametrize("interface", [ME, CS])
@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_feedthrough_holds_the_inputs_not_given_at_their_starts(reference, version, interface):
    """No input given: every one held at its start value, noted by name and value, and the
    outputs are fmpy's; one given: it passes through, the others stay held."""
    path = reference[version, "Feedthrough"]
    sim = Simulator(path, interface=interface)
    with pytest.warns(InputsHeld, match=r"Float64_continuous_input = 0.*Int32_input = 0.*Boolean_input = false.*"
                                        r"String_input = 'Set me!'.*Enumeration_input = 1"):
        traj = _quiet_outputs(ref.ours, sim, "Feedthrough", interface)
    assert ref.largest_difference(traj, _quiet(ref.fmpy_run, path, "Feedthrough", interface)) == 0.0
    time, ramp = np.array([0.0, 2.0]), np.array([1.0, 3.0])
    given = _quiet(ref.ours, sim, "Feedthrough", interface,
                   input_time=time, inputs={"Float64_continuous_input": ramp})
    signal = np.array(list(zip(time, ramp)), dtype=[("time", float), ("Float64_continuous_input", float)])
    theirs = _quiet(ref.fmpy_run, path, "Feedthrough", interface, input=signal)
    assert ref.largest_difference(given, theirs) < 1e-12
    if interface == ME:  # Co-Simulation holds an input over a step: the FMU does not interpolate it
        np.testing.assert_allclose(given["Float64_continuous_output"], 1.0 + given.time, atol=1e-12)
    assert np.all(given["Int32_output"] == 0) and np.all(given["Enumeration_output"] == 1)


def _quiet_outputs(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OutputsSkipped)
        return fn(*args, **kw)


def test_what_is_refused_names_the_fmi_feature_it_needs(reference):
    """Clocks (Scheduled Execution, clocked partitions) is refused by name; a String or
    Binary output asked for by name is refused; every numeric output, of every FMI 3.0 type
    and an array's elements, is recordable."""
    with pytest.raises(FmuError, match=r"only a Scheduled Execution interface \(model partitions activated by "
                                       r"FMI 3.0 clocks inClock1, inClock2, inClock3, outClock\)"):
        Simulator(reference["3.0", "Clocks"])
    feed = Simulator(reference["3.0", "Feedthrough"])
    for name, kind in (("String_output", "String"), ("Binary_output", "Binary")):
        with pytest.raises(ParameterError, match=rf"cannot record {name} \({kind}\)"):
            _quiet(feed.simulate, {}, stop_time=1.0, output_interval=0.5, outputs=[name])
    numeric = [n for n in feed.outputs if feed.fmu.types[n] not in ("String", "Binary")]
    assert len(numeric) == 14 and feed.fmu.numeric_outputs == numeric
    traj = _quiet(feed.simulate, {}, stop_time=1.0, output_interval=0.5, outputs=numeric)
    assert list(traj.outputs) == numeric
    space = Simulator(reference["3.0", "StateSpace"])
    traj = _quiet(space.simulate, {}, stop_time=1.0, output_interval=0.5, outputs=["y", "x[2]"])
    assert list(traj.outputs) == ["y[1]", "y[2]", "y[3]", "x[2]"]
    np.testing.assert_allclose(traj["y[3]"], 3.0 * np.exp(traj.time), rtol=1e-12)
    assert traj["y"].shape == (traj.time.size, 3)  # by the array's name: one (times, 3) array, as fmpy gives it
    np.testing.assert_array_equal(traj["y"][:, 2], traj["y[3]"])
    with pytest.raises(KeyError, match=r"'z': no such output; recorded: y\[1\], y\[2\], y\[3\], x\[2\]"):
        traj["z"]


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


@pytest.mark.skipif(not os.path.exists("/proc/self/statm"), reason="reads the resident set size from /proc")
def test_instantiating_an_fmi3_reference_fmu_again_and_again_keeps_memory_flat(reference):
    """A reduced size of make bench's 10,000: 300 fresh instantiations of FMI 3.0
    BouncingBall (extracted, loaded, run, freed) and 1,500 Stair Co-Simulation sets, each a
    new instance (a set the model terminated leaves its instance)."""
    ball, stair = reference["3.0", "BouncingBall"], reference["3.0", "Stair"]

    def fresh():
        sim = Simulator(ball)
        sim.simulate({}, stop_time=1.0, output_interval=0.1)
        sim.close()

    steps = Simulator(stair, interface=CS)
    grid = dict(stop_time=10.0, output_interval=1.0)
    for _ in range(20):
        fresh()
        _quiet(steps.simulate_batch, [], np.zeros((10, 0)), **grid)
    before = _rss_mb()
    for _ in range(300):
        fresh()
    for _ in range(150):
        batch = _quiet(steps.simulate_batch, [], np.zeros((10, 0)), **grid)
        assert np.all(batch.values[:, 9, 0] == 10.0)  # every set stops at t = 9 s with its count
    assert _rss_mb() - before < 3.0
