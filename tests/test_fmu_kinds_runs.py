"""Every kind of FMU (FMI 2.0 / 3.0 x Model Exchange / Co-Simulation) through the whole
tool: calibrations of the droop plant twins that agree with its FMI 2.0 Model Exchange FMU
and rerun identically, a model that asks to terminate (a failed simulation in a
calibration, with its message archived; a trajectory with a warning on the command line),
and memory that stays flat over thousands of simulations and instantiations.
"""

from __future__ import annotations

import os
import textwrap
import warnings

import numpy as np
import pytest

import rapid_cosim as rc
from rapid_cosim.archive import RunArchive
from rapid_cosim.cli import main
from rapid_cosim.errors import ConfigError
from rapid_cosim.simulator import Simulator
from rapid_cosim.simulator.simulation import OutputsSkipped

from c_fmus import KINDS, build_kind
from test_measured_inputs import FAST, _droop_config, _droop_recording

TWINS = [k for k in KINDS if k != "me2"]


@pytest.fixture(scope="module")
def droop(tmp_path_factory):
    folder = tmp_path_factory.mktemp("droop_kinds")
    return {kind: build_kind("DroopPlant", folder, kind) for kind in KINDS}


def _fit(fmu, folder, extra=""):
    _droop_recording(folder)
    config = _droop_config(folder, fmu, extra=extra)
    fit = rc.calibrate(config, "pso:6+nm", archive=folder / "run.h5", options=FAST)
    return fit, folder / "run.h5"


@pytest.fixture(scope="module")
def me2_fit(droop, tmp_path_factory):
    fit, _ = _fit(droop["me2"], tmp_path_factory.mktemp("me2"))
    return fit


@pytest.mark.parametrize("kind", TWINS)
def test_droop_twins_calibrate_as_the_fmi2_model_exchange_fmu_and_rerun_identically(droop, me2_fit, kind,
                                                                                     tmp_path):
    fit, archive = _fit(droop[kind], tmp_path)
    np.testing.assert_allclose(fit.x, me2_fit.x, rtol=1e-3)  # R and T within 0.1 %
    np.testing.assert_allclose(fit.x, [0.05, 2.0], rtol=2e-3)
    with RunArchive(archive) as view:
        [path] = view.options["simulation_paths"].values()  # per model, here the FMU's path
    version, interface = KINDS[kind]
    assert path.startswith(f"FMI {version} {'Co-Simulation' if interface == 'CS' else 'Model Exchange'}")
    again = rc.rerun(archive)
    assert again.identical, again.message


def test_a_communication_step_set_in_the_config_is_used_and_checked(droop, me2_fit, tmp_path):
    fit, archive = _fit(droop["cs3"], tmp_path, extra="communication_step = 0.01")
    np.testing.assert_allclose(fit.x, me2_fit.x, rtol=1e-3)
    assert rc.rerun(archive).identical
    bad = tmp_path / "bad"
    bad.mkdir()
    _droop_recording(bad)
    with pytest.raises(ConfigError, match="simulation.communication_step"):
        rc.calibrate(_droop_config(bad, droop["cs3"], extra="communication_step = -1.0"), "pso:2",
                     archive=bad / "run.h5", options=FAST)


# --------------------------------------------------------------------------- terminate requests


def _counter_experiment(folder, fmu):
    """x of a Counter (period 1 s) over 10 s; stop_at estimated in [6, 14] s: a run that
    stops before the last sample (10 s) is a failed simulation."""
    t = np.arange(0.0, 10.0 + 1e-9, 0.1)
    k = np.floor(t + 1e-9)
    x = k * (k - 1) / 2 + k * (t - k)
    (folder / "counter.csv").write_text("time,x\n" + "".join(f"{a:.1f},{b:.9f}\n" for a, b in zip(t, x)))
    (folder / "config.toml").write_text(textwrap.dedent(f"""\
        [experiment]
        name = "counter"
        fmu = "{fmu}"

        [data]
        file = "counter.csv"
        outputs = {{ x = "x" }}

        [estimate]
        period = {{ min = 0.8, max = 1.25 }}
        stop_at = {{ min = 6.0, max = 14.0 }}

        [simulation]
        stop_time = 10.0
        output_interval = 0.1
        """))
    return folder / "config.toml"


@pytest.mark.parametrize("kind", ["me2", "cs3"])
def test_a_run_that_stops_before_the_last_sample_is_a_failed_simulation_with_its_message_archived(kind, tmp_path):
    fmu = build_kind("Counter", tmp_path / "fmu", kind)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OutputsSkipped)
        fit = rc.calibrate(_counter_experiment(tmp_path, fmu), "pso:3", archive=tmp_path / "run.h5",
                           options={"pso": {"n_particles": 12}})
    with RunArchive(tmp_path / "run.h5") as view:
        ev, result = view.evaluations(), view.result()
    early = ev.x[:, 1] < 10.0 - 1e-9
    assert early.any() and (~early).any()
    np.testing.assert_array_equal(ev.failed, early)  # and only those
    assert result.n_failed == early.sum() and fit.x[1] >= 10.0
    assert result.failure_messages and all("asked to terminate at t=" in m for m in result.failure_messages)
    assert rc.rerun(tmp_path / "run.h5").identical


@pytest.mark.parametrize("kind", ["cs2", "me3"])
def test_the_command_line_writes_the_trajectory_up_to_the_stop_with_a_warning(kind, tmp_path, capsys):
    fmu = build_kind("Counter", tmp_path, kind)
    out = tmp_path / "x.csv"
    assert main(["simulate", str(fmu), "--set", "stop_at=7.2", "--stop-time", "10", "--output-interval", "0.5",
                 "--outputs", "x,count", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "asked to terminate the simulation at t=7.2 s" in err and "ends at t=7 s" in err
    rows = out.read_text().splitlines()
    assert rows[0] == "time,x,count" and len(rows) == 1 + 15 and rows[-1].startswith("7,21.0,7.0")


def test_a_string_output_no_longer_blocks_the_command_line(tmp_path, capsys):
    fmu = build_kind("Counter", tmp_path, "cs2")
    assert main(["simulate", str(fmu), "--stop-time", "2", "--output-interval", "1"]) == 0
    captured = capsys.readouterr()
    assert "label (String) are not numbers and are not recorded" in captured.err
    assert captured.out.splitlines()[0] == "time,x,count,odd"


# --------------------------------------------------------------------------- memory


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


@pytest.mark.skipif(not os.path.exists("/proc/self/statm"), reason="reads the resident set size from /proc")
@pytest.mark.parametrize("kind", KINDS)
def test_memory_stays_flat_over_thousands_of_simulations_and_instantiations(droop, kind):
    """A reduced size of ``make bench``'s 10,000 per kind: 2,000 rc.simulate calls (one
    instance, reset per run) and 200 fresh instantiations (FMU extracted, loaded, freed)."""
    inputs = dict(input_time=np.array([0.0, 1.0, 1.0, 10.0]), inputs={"dw": np.array([0.0, 0.0, 0.01, 0.01])})
    grid = dict(stop_time=10.0, output_interval=0.05, **inputs)

    def fresh():
        sim = Simulator(droop[kind])
        sim.simulate({"R": 0.05}, **grid)
        sim.close()
        sim.fmu.close()

    for i in range(100):  # warm up: libraries loaded, allocator pools made
        rc.simulate(droop[kind], {"R": 0.05 + 1e-6 * i}, **grid)
        fresh() if i < 20 else None
    before = _rss_mb()
    for i in range(2000):
        rc.simulate(droop[kind], {"R": 0.05 + 1e-6 * i}, **grid)
    for _ in range(200):
        fresh()
    assert _rss_mb() - before < 3.0
