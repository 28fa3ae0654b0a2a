"""Experiments driven by measured inputs, and FMUs the embedded compiler did not make:
the event1 recording, joint fits with staged tests, [inputs] conversions and their
errors, and a C-written FMU that calibrates and reruns from its archive alone."""

from __future__ import annotations

import shutil
import textwrap
from pathlib import Path

import numpy as np
import pytest

import rapid_cosim as rc
from rapid_cosim.errors import ConfigError, RapidCosimError
from rapid_cosim.experiment import load_experiment

from c_fmus import build_c_fmu
from rapid_cosim.compiler.source import ModelSource

FAST = {"pso": {"n_particles": 12}, "nm": {"max_fev": 60}}


# --------------------------------------------------------------------------- event1


def test_event1_recording_is_what_its_generator_makes(repo, fmus, tmp_path):
    import importlib.util

    spec = importlib.util.spec_from_file_location("generate", repo / "experiments/event1/generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    cfg = module.generate(tmp_path, fmu_dir=repo / "fmus")
    for suffix in (".cfg", ".dat"):
        assert cfg.with_suffix(suffix).read_bytes() == (repo / "experiments/event1/event1").with_suffix(
            suffix).read_bytes()


def test_event1_recovers_the_synthetic_plant(repo, fmus, tmp_path):
    fit = rc.calibrate(repo / "experiments/event1", "pso:10+nm", archive=tmp_path / "ev.h5",
                       source=ModelSource(fmu_dir=repo / "fmus", package=repo / "modelica/iGrGen"))
    R, Ts = fit.parameters["gov.R"], fit.parameters["gov.Ts"]
    assert abs(R / 0.055 - 1) < 0.02, R
    assert abs(Ts / 1.6 - 1) < 0.15, Ts


def test_event1_input_is_the_recorded_frequency_converted(repo):
    exp = load_experiment(repo / "experiments/event1")
    table = exp.input_table
    freq = exp.data.columns["FREQ"]
    pre = exp.data.time < 20.0
    np.testing.assert_allclose(table.values[:, 0], freq - freq[pre].mean(), atol=1e-12)
    measured, _ = exp.measured("pm")
    np.testing.assert_allclose(measured, exp.data.columns["P"] * 0.0025)


def test_joint_fit_of_a_staged_test_and_the_event_reruns_bit_identical(repo, fmus, tmp_path):
    fit = rc.calibrate([repo / "experiments/test1", repo / "experiments/event1"], "pso:3+nm",
                       archive=tmp_path / "joint.h5", options=FAST, source=ModelSource(fmu_dir=repo / "fmus", package=repo / "modelica/iGrGen"))
    assert fit.success and fit.labels == ("R", "Ts")
    again = rc.rerun(tmp_path / "joint.h5")
    assert again.identical, again.message
    np.testing.assert_array_equal(again.x, fit.x)


# --------------------------------------------------------------------------- [inputs]


def _droop_recording(folder: Path, *, gap: int = 0, separate: bool = False, stop: float = 30.0):
    """f (Hz) falling by 0.1 Hz from 5 s with a 3 s time constant, and the DroopPlant's p
    (R 0.05, T 2 s, p_ref 0.6: a first-order lag of 0.6 - dw / R), in closed form."""
    t = np.arange(0.0, stop + 1e-9, 0.05)
    tau = np.clip(t - 5.0, 0.0, None)
    f = 50.0 - 0.1 * (1 - np.exp(-tau / 3.0))
    p = 0.6 + 0.04 * (1 - (3.0 * np.exp(-tau / 3.0) - 2.0 * np.exp(-tau / 2.0)) / (3.0 - 2.0))
    f_cells = [f"{v:.6f}" for v in f]
    f_cells[200:200 + gap] = [""] * gap
    if separate:
        (folder / "out.csv").write_text("time,p\n" + "".join(f"{a:.2f},{b:.9f}\n" for a, b in zip(t, p)))
        (folder / "freq.csv").write_text("t,f\n" + "".join(f"{a:.2f},{b}\n" for a, b in zip(t, f_cells)))
    else:
        (folder / "rec.csv").write_text("time,f,p\n" + "".join(
            f"{a:.2f},{b},{c:.9f}\n" for a, b, c in zip(t, f_cells, p)))


def _droop_config(folder: Path, fmu: Path, *, data="rec.csv", inputs=None, extra=""):
    inputs = inputs or ('dw = { column = "f", unit = "Hz", convert = "deviation_pu", nominal = 50.0 }')
    text = textwrap.dedent(f"""\
        [experiment]
        name = "droop"
        fmu = "{fmu}"

        [data]
        file = "{data}"
        outputs = {{ p = "p" }}

        [inputs]
        {inputs}

        [fixed]
        p_ref = 0.6

        [estimate]
        R = {{ min = 0.02, max = 0.12 }}
        T = {{ min = 0.2, max = 10.0 }}

        [simulation]
        stop_time = 30.0
        output_interval = 0.05
        {extra}
        """)
    (folder / "config.toml").write_text(text)
    return folder / "config.toml"


@pytest.fixture(scope="module")
def droop_fmus(tmp_path_factory):
    folder = tmp_path_factory.mktemp("c_fmus")
    return {"me": build_c_fmu("DroopPlant", folder), "cs": build_c_fmu("DroopPlant", folder, model_exchange=False,
                                                                        co_simulation=True),
            "other": build_c_fmu("DroopPlant", folder, platform="aarch64-darwin")}


def test_an_outside_fmu_calibrates_and_reruns_from_its_archive_alone(droop_fmus, tmp_path):
    own = tmp_path / "Plant.fmu"
    shutil.copy(droop_fmus["me"], own)
    _droop_recording(tmp_path)
    config = _droop_config(tmp_path, own)
    fit = rc.calibrate(config, "pso:6+nm", archive=tmp_path / "run.h5", options=FAST)
    np.testing.assert_allclose(fit.x, [0.05, 2.0], rtol=2e-3)
    own.unlink()
    (tmp_path / "rec.csv").unlink()  # neither the FMU nor the data is needed again
    again = rc.rerun(tmp_path / "run.h5")
    assert again.identical, again.message


def test_inputs_from_another_file_align_by_time(droop_fmus, tmp_path):
    _droop_recording(tmp_path, separate=True)
    config = _droop_config(tmp_path, droop_fmus["me"], data="out.csv", inputs=(
        'dw = { column = "f", file = "freq.csv", time = "t", convert = "deviation_pu", nominal = 50.0 }'))
    fit = rc.calibrate(config, "pso:6+nm", archive=tmp_path / "run.h5", options=FAST)
    np.testing.assert_allclose(fit.x, [0.05, 2.0], rtol=2e-3)
    (tmp_path / "freq.csv").unlink()
    assert rc.rerun(tmp_path / "run.h5").identical


@pytest.mark.parametrize("fmu_key, message", [  # Co-Simulation-only FMUs run: tests/test_fmu_kinds.py
    ("other", r"\[experiment.fmu\].*no binary for this platform.*aarch64-darwin"),
])
def test_fmus_that_cannot_run_are_refused_by_key(droop_fmus, tmp_path, fmu_key, message):
    _droop_recording(tmp_path)
    config = _droop_config(tmp_path, droop_fmus[fmu_key])
    with pytest.raises(RapidCosimError, match=message):
        rc.calibrate(config, "pso:2", archive=tmp_path / "run.h5", options=FAST)
    assert not (tmp_path / "run.h5").exists()


@pytest.mark.parametrize("edit, message", [
    (("outputs = { p = \"p\" }", "outputs = { power = \"p\" }"), r"\[data.outputs.power\].*no output 'power'"),
    (("R = { min", "Rd = { min"), r"\[estimate.Rd\].*no parameter 'Rd'"),
    (("dw = {", "omega = {"), r"\[inputs.omega\].*no input 'omega'; its inputs: dw"),
])
def test_outside_fmu_variables_named_in_the_config_must_exist(droop_fmus, tmp_path, edit, message):
    _droop_recording(tmp_path)
    config = _droop_config(tmp_path, droop_fmus["me"])
    config.write_text(config.read_text().replace(*edit))
    with pytest.raises(RapidCosimError, match=message):
        rc.calibrate(config, "pso:2", archive=tmp_path / "run.h5", options=FAST)


def test_a_short_gap_in_an_input_is_bridged_and_said(droop_fmus, tmp_path):
    """Three blank samples (0.15 s): bridged by interpolation, the outputs kept, the
    bridge named in the recording's words."""
    _droop_recording(tmp_path, gap=3)
    config = _droop_config(tmp_path, droop_fmus["me"])
    with pytest.warns(Warning):
        exp = load_experiment(config)
    (bridge,) = exp.recording.bridges
    assert (bridge.before, bridge.after, bridge.excluded) == (9.95, 10.15, None)
    assert bridge.seconds == pytest.approx(0.15)
    assert "input 'f': 1 hole(s) bridged by linear interpolation, the longest 0.15 s (9.95-10.15 s)" in \
        exp.recording.lines()
    table = exp.input_table
    assert np.all(np.isfinite(table.values)) and exp.data.n_valid("p") == len(exp.data)


def test_a_long_gap_in_an_input_is_refused_at_its_time_unless_asked(droop_fmus, tmp_path):
    """2 s blank: refused with the column, the times and the option that bridges it; with
    the option, bridged, and the outputs in and near the gap left out of the fit."""
    _droop_recording(tmp_path, gap=40)
    config = _droop_config(tmp_path, droop_fmus["me"])
    with pytest.warns(Warning), pytest.raises(
            ConfigError, match=r"\[inputs.dw\].*column 'f' has no valid sample between 9.95 s and 12 s \(2 s\).*"
                               r"add gaps = \{ max = 2, fill = \"linear\" \}"):
        load_experiment(config)
    inputs = 'dw = { column = "f", unit = "Hz", convert = "deviation_pu", nominal = 50.0, gaps = { max = 1.5 } }'
    config = _droop_config(tmp_path, droop_fmus["me"], inputs=inputs)
    with pytest.warns(Warning), pytest.raises(ConfigError, match=r"longer than 1.5 s.*its gaps.max is 1.5 s"):
        load_experiment(config)
    config.write_text(config.read_text().replace("max = 1.5", "max = 2.0"))
    with pytest.warns(Warning):
        exp = load_experiment(config)
    (bridge,) = exp.recording.bridges
    assert bridge.excluded == pytest.approx((9.8, 14.0))
    left = ~exp.data.valid["p"]
    assert np.array_equal(exp.data.time[left], exp.data.time[(exp.data.time >= 9.8) & (exp.data.time <= 14.0)])
    assert "outputs left out of the fit over 9.8-14 s" in exp.recording.lines()[-1]


def test_an_input_that_stops_before_the_simulation_is_refused(droop_fmus, tmp_path):
    _droop_recording(tmp_path, separate=True, stop=20.0)
    (tmp_path / "out.csv").write_text("time,p\n" + "".join(f"{0.05 * k:.2f},0.6\n" for k in range(601)))
    config = _droop_config(tmp_path, droop_fmus["me"], data="out.csv", inputs=(
        'dw = { column = "f", file = "freq.csv", time = "t", convert = "deviation_pu", nominal = 50.0 }'))
    with pytest.raises(ConfigError, match=r"\[inputs.dw\].*from 0 s to 20 s, the simulation runs 0 s to 30 s"):
        load_experiment(config)


@pytest.mark.parametrize("entry, message", [
    ('dw = { column = "f", unit = "furlong" }', r"\[inputs.dw.unit\].*'furlong' is not known"),
    ('dw = { column = "f", convert = "deviation" }', r"\[inputs.dw\].*needs the nominal value"),
    ('dw = { column = "f", sign = 2 }', r"\[inputs.dw.sign\].*1 or -1"),
    ('dw = { column = "freq" }', r"\[inputs.dw.column\].*no column 'freq'; columns present: f, p"),
    ('dw = { column = "f", colour = "red" }', r"inputs.dw.*colour"),
])
def test_bad_input_entries_name_their_key(droop_fmus, tmp_path, entry, message):
    _droop_recording(tmp_path)
    config = _droop_config(tmp_path, droop_fmus["me"], inputs=entry)
    with pytest.raises(ConfigError, match=message):
        load_experiment(config)


def test_simulate_given_an_experiment_says_what_it_takes(repo):
    """rc.simulate takes a model name or an .fmu; an Experiment passed instead used to
    fail deep in the build with the experiment's whole repr as the 'unknown model'."""
    from rapid_cosim.errors import ParameterError
    from rapid_cosim.experiment import load_experiment

    exp = load_experiment(repo / "experiments" / "test1")
    with pytest.raises(ParameterError, match=r"got Experiment: an experiment is simulated through its model"):
        rc.simulate(exp, {})
    with pytest.raises(ParameterError, match="got int"):
        rc.simulate(3)
