"""Electrical power at the terminals (issue 26): the swing term against scipy, the ROCOF
filter, every bad input, and events from ANDES's GENROU in the Kundur two-area grid
(experiments/electrical, made by its generate.py) calibrated on P_e and as if it were P_m."""

from __future__ import annotations

import importlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description
from reference_standard import Standard

import rapid_cosim as rc
from rapid_cosim.errors import ConfigError
from rapid_cosim.experiment import load_experiment
from rapid_cosim.experiment.electrical import D_RANGE, H_RANGE
from rapid_cosim.simulator import Simulator
from rapid_cosim.simulator.rocof import derive_rocof, noise_gain
from rapid_cosim.compiler.source import ModelSource

F_NOM = 60.0
T = np.arange(0.0, 40.0, 0.02)


def _event(t):
    """A smooth under-frequency excursion (Hz) and its exact derivative (Hz/s): a nadir
    near -0.25 Hz, a settled -0.12 Hz, a 0.6 Hz swing on the way."""
    s = np.clip(t - 5.0, 0.0, None)
    f = -0.12 * (1 - np.exp(-s / 2.0)) ** 2 - 0.2 * s / 1.5 * np.exp(-s / 1.5) * (1 + 0.2 * np.sin(3.8 * s))
    return f, np.gradient(f, t, edge_order=2)


class Driven(Standard):
    """The published diagram driven by a recorded frequency, P_e from the swing equation."""

    def __init__(self, model, params, h, d, torque):
        super().__init__(model, params)
        self.h, self.d, self.torque = h, d, torque

    def dw(self, t):
        return -np.interp(t, T, _event(T)[0]) / F_NOM

    def _f(self, t, x):
        dx, pm = super()._f(t, x)
        if self.model == "GGOV1":  # its droop reads P_e, lagged by Tpelec
            dx = list(dx)
            dx[0] += (self.pe(t, pm) - pm) / self.p["Tpelec"]
        return dx, pm

    def pe(self, t, pm):
        dw = np.interp(t, T, _event(T)[0]) / F_NOM
        dwdt = np.interp(t, T, _event(T)[1]) / F_NOM
        return (1 + self.torque * dw) * pm - (1 + dw) * (2 * self.h * dwdt + self.d * dw)


@pytest.mark.parametrize("model", ["TGOV1", "IEEEG1", "GGOV1"])
@pytest.mark.parametrize("torque", [0.0, 1.0])
def test_electrical_power_matches_the_swing_equation(fmus, model, torque):
    params = {"mach.H": 6.5, "mach.D": 1.5, "mach.torque": torque, "f_nom": F_NOM}
    f, rocof = _event(T)
    traj = Simulator(fmus[f"FrequencyInput{model}"]).simulate(
        params, output_times=T, input_time=T, inputs={"f_dev": f, "rocof": rocof}, outputs=["pm", "pe"])
    ref = Driven(model, {"src.t_step": 1e9}, 6.5, 1.5, torque)
    pm = ref.simulate(T)
    pe = np.array([ref.pe(t, p) for t, p in zip(T, pm)])
    assert np.max(np.abs(traj["pm"] - pm)) < 2e-4
    assert np.max(np.abs(traj["pe"] - pe)) < 2e-4
    assert np.max(np.abs(pe - pm)) > 0.03  # the swing term is there to be checked


def test_the_machine_constants_ranges_are_the_configs(fmus):
    by_name = {v.name: v for v in read_model_description(str(fmus["FrequencyInputTGOV1"])).modelVariables}
    assert (float(by_name["mach.H"].min), float(by_name["mach.H"].max)) == H_RANGE
    assert (float(by_name["mach.D"].min), float(by_name["mach.D"].max)) == D_RANGE
    assert by_name["rocof"].causality == "input" and by_name["rocof"].unit == "Hz/s"
    assert by_name["pe"].causality == "output"


def test_the_rocof_filter_is_exact_on_a_quadratic_and_its_noise_gain_is_measured():
    t = np.arange(0.0, 10.0, 0.02)
    assert np.max(np.abs(derive_rocof(t, 0.3 * t ** 2 - t) - (0.6 * t - 1))) < 1e-9
    rng = np.random.default_rng(3)
    draws = np.array([derive_rocof(t, rng.standard_normal(t.size))[50:-50] for _ in range(200)])
    assert np.std(draws) == pytest.approx(noise_gain(0.02), rel=0.05)


def test_the_sample_at_the_event_time_keeps_the_rocof_before_it():
    """A frequency that starts falling at 5 s, sampled at 5 s: the sample at the break is
    the last before the event (its P_e has not moved), the next one the first after."""
    t = np.arange(0.0, 10.0, 0.02)
    f = -0.1 * np.clip(t - 5.0, 0.0, None)
    rocof = derive_rocof(t, f, breaks=(5.0,))
    at = int(np.argmin(np.abs(t - 5.0)))
    assert rocof[at] == pytest.approx(0.0, abs=1e-9) and rocof[at + 1] == pytest.approx(-0.1, rel=1e-6)
    assert np.max(np.abs(rocof[:at + 1])) < 1e-9 and np.max(np.abs(rocof[at + 1:] + 0.1)) < 1e-9


def test_a_bench_without_rocof_gets_the_derived_one(fmus):
    f, rocof = _event(T)
    sim = Simulator(fmus["FrequencyInputTGOV1"])
    derived = sim.simulate({"mach.H": 6.5}, output_times=T, input_time=T, inputs={"f_dev": f}, outputs=["pe"])
    exact = sim.simulate({"mach.H": 6.5}, output_times=T, input_time=T, inputs={"f_dev": f, "rocof": rocof},
                         outputs=["pe"])
    gap = np.abs(derived["pe"] - exact["pe"])
    kink = np.abs(T - 5.0) < 0.3  # the event starts with a ROCOF step, spread over the window
    assert np.max(gap[~kink]) < 2e-3  # elsewhere the 0.3 s filter on a 0.6 Hz swing
    assert np.max(gap[kink]) < 2 * 6.5 / F_NOM * np.max(np.abs(rocof))


def test_the_derived_rocof_does_not_bias_droop_or_time_constants(fmus, tmp_path):
    """Own bench, exact ROCOF in the plant, derived ROCOF in the fit, 1 mHz frequency noise."""
    truth = {"gov.R": 0.05, "gov.T1": 0.5, "gov.T3": 7.0, "gov.T2": 2.1}
    f, rocof = _event(T)
    sim = Simulator(fmus["FrequencyInputTGOV1"])
    pe = sim.simulate({**truth, "mach.H": 6.5, "f_nom": F_NOM}, output_times=T, input_time=T,
                      inputs={"f_dev": f, "rocof": rocof}, outputs=["pe"])["pe"]
    rng = np.random.default_rng(5)
    freq = F_NOM + f + 1e-3 * rng.standard_normal(T.size)
    _write(tmp_path, freq, pe * 900.0, _CONFIG)
    fit = rc.calibrate([tmp_path], method="ms", seed=1, source=ModelSource(fmu_dir=fmus["FrequencyInputTGOV1"].parent))
    got = dict(zip(fit.names, fit.x))
    assert got["gov.R"] == pytest.approx(0.05, rel=0.01)
    assert got["gov.T1"] == pytest.approx(0.5, rel=0.08) and got["gov.T3"] == pytest.approx(7.0, rel=0.03)


_CONFIG = """
[experiment]
model = "iGrGen.TestBenches.FrequencyInputTGOV1"
[data]
file = "data.csv"
outputs = { pe = { column = "P", unit = "MW", rating = 900.0 } }
[inputs]
f_dev = { column = "FREQ", unit = "Hz", convert = "deviation", nominal = 60.0, baseline = "pre-event" }
[fixed]
f_nom = 60.0
"gov.T2" = 2.1
"mach.H" = 6.5
[estimate]
"gov.R" = { min = 0.02, max = 0.12 }
"gov.T1" = { min = 0.05, max = 3.0 }
"gov.T3" = { min = 1.0, max = 20.0 }
[fitness]
offset = true
noise = "pre-step"
pre_step_end = 5.0
"""


def _write(folder: Path, freq, power, config: str, rocof=None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    cols = {"time": T, "FREQ": freq, "P": power, **({"ROCOF": rocof} if rocof is not None else {})}
    with (folder / "data.csv").open("w") as fh:
        fh.write(",".join(cols) + "\n")
        fh.writelines(",".join(f"{c[k]:.6f}" for c in cols.values()) + "\n" for k in range(T.size))
    (folder / "config.toml").write_text(config)
    return folder / "config.toml"


# --------------------------------------------------------------------------- bad input


def _bad(tmp_path, config: str, rocof=None):
    f, _ = _event(T)
    path = _write(tmp_path, F_NOM + f, 700.0 + 1000 * f, config, rocof)
    return load_experiment(path)


_H_ESTIMATED_LOW = _CONFIG.replace('"mach.H" = 6.5\n', "").replace(
    "[estimate]\n", '[estimate]\n"mach.H" = { min = 0.1, max = 12.0 }\n')


@pytest.mark.parametrize("config, field, message", [
    (_CONFIG.replace('"mach.H" = 6.5\n', ""), r"\[data.outputs.pe\]", r"needs the unit's inertia constant H.*0.5 to 15 s"),
    (_CONFIG.replace('"mach.H" = 6.5', '"mach.H" = 65.0'), r"\[fixed.\"mach.H\"\]", r"mach.H = 65 s is outside the allowed 0.5 to 15"),
    (_CONFIG.replace('"mach.H" = 6.5\n', '"mach.D" = -1.0\n"mach.H" = 6.5\n'), r"\[fixed.\"mach.D\"\]",
     r"-1 pu is outside .*0 to 5"),
    (_H_ESTIMATED_LOW, r"\[estimate.\"mach.H\".min\]", r"min = 0.1 s is outside the allowed 0.5 to 15 s"),
], ids=["no H", "H fixed too large", "D negative", "H bounds too low"])
def test_electrical_power_without_a_valid_inertia_is_an_error(tmp_path, config, field, message):
    with pytest.raises(ConfigError, match=field) as err:
        _bad(tmp_path, config)
    assert str(tmp_path / "config.toml") in str(err.value)
    assert err.match(message)


def test_megawatts_without_a_rating_is_an_error(tmp_path):
    with pytest.raises(ConfigError, match=r"\[data.outputs.pe\].*MW needs the unit's rating.*rating > 0"):
        _bad(tmp_path, _CONFIG.replace(', rating = 900.0', ''))
    with pytest.raises(ConfigError, match=r"\[data.outputs.pe.rating\].*> 0; got -900"):
        _bad(tmp_path, _CONFIG.replace('rating = 900.0', 'rating = -900.0'))


@pytest.mark.parametrize("factor, unit, message", [
    (-1.0, "Hz/s", r"-(0.9[89]|1.0[12]) times the derivative of the frequency \(f_dev\): a wrong sign\? allowed 0.5 to 2"),
    (1000.0, "Hz/s", r"(9[89]\d|1.0[12]e\+03) times the derivative.*wrong unit.*allowed 0.5 to 2"),
    (1.0 / F_NOM, "Hz/s", r"0.01[67]\d? times the derivative.*wrong unit"),
])
def test_a_rocof_column_that_is_not_the_frequencys_derivative_is_an_error(tmp_path, factor, unit, message):
    _, rocof = _event(T)
    config = _CONFIG.replace('baseline = "pre-event" }\n', f'baseline = "pre-event" }}\nrocof = {{ column = "ROCOF", '
                                                           f'unit = "{unit}" }}\n')
    with pytest.raises(ConfigError, match=r"\[inputs.rocof\].*column 'ROCOF' is " + message):
        _bad(tmp_path, config, rocof * factor)
    ok = _bad(tmp_path, config.replace('"Hz/s"', '"mHz/s"'), rocof * 1000.0)  # the same in its own unit
    assert "rocof" in ok.input_table.names


def test_rocof_noise_joins_the_fitness_noise_of_electrical_power(tmp_path):
    f, _ = _event(T)
    rng = np.random.default_rng(2)
    _write(tmp_path, F_NOM + f + 2e-3 * rng.standard_normal(T.size), 700.0 + rng.standard_normal(T.size), _CONFIG)
    exp = load_experiment(tmp_path)
    power_only = 1.0 / 900.0
    rocof_part = 2 * 6.5 / F_NOM * 2e-3 * noise_gain(0.02)
    assert exp.noise_sigma["pe"] == pytest.approx(np.hypot(power_only, rocof_part), rel=0.15)
    assert exp.noise_sigma["pe"] > 1.3 * power_only


# --------------------------------------------------------------------------- ANDES events

EVENTS = ["tgov1_on", "tgov1_off", "ieeeg1_on", "tgtypei_on"]


# the test's names for benchmarks/electrical_study.py's readings of an event
KINDS = {"H fixed": "P_e, H fixed", "H estimated": "P_e, H estimated", "as if pm": "as if P_m", "noise-free": "noise-free"}


def _study():
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import electrical_study

    return electrical_study


def _variant(folder: Path, kind: str):
    return _study().variant(folder, KINDS[kind])


def _errors(repo, fmus, event: str, kind: str) -> dict[str, float]:
    return _study().errors(repo / "experiments" / "electrical" / event, KINDS[kind], fmus["FrequencyInput"].parent)


@pytest.mark.parametrize("event", EVENTS)
def test_andes_events_calibrate_on_electrical_power(repo, fmus, event):
    fixed = _errors(repo, fmus, event, "H fixed")
    droop = "gov.K" if "gov.K" in fixed else "gov.R"
    assert abs(fixed[droop]) < 0.02
    slow = {"gov.T3", "gov.T5"}  # the reheater / second stage
    assert all(abs(e) < 0.15 for name, e in fixed.items() if name in slow)
    # the fast lag (T1, T4, Ts): these four noise draws give -13, -4, -14 and +3.5 %; over
    # 20 other draws per event of the first three its error is -1.7 +- 8.0, +0.9 +- 4.9 and
    # -2.8 +- 5.3 % (mean +- sd; see the noise-free test below and benchmarks/electrical_study.py)
    assert all(abs(e) < 0.20 for e in fixed.values())
    free = _errors(repo, fmus, event, "H estimated")
    assert abs(free["mach.H"]) < 0.10 and abs(free[droop]) < 0.02
    assert all(abs(e) < 0.20 for e in free.values())
    as_pm = _errors(repo, fmus, event, "as if pm")  # the bias electrical power removes
    assert abs(as_pm[droop]) > 0.05 and max(abs(e) for e in as_pm.values()) > 0.5


@pytest.mark.parametrize("event", EVENTS)
def test_without_the_recorders_noise_the_fast_lag_is_within_4_percent(repo, fmus, event):
    """The same samples without noise (clean.csv), the ROCOF still derived: what is left
    of the fast lag's error is the model's, not the noise draw's. Measured: T1 -0.7 and
    +0.7 %, T4 -2.6 %, TG Type I's Ts -1.0 % (R +0.06 %, T5 +0.2 %). With ANDES's exact
    ROCOF instead (the first three): -1.2, +0.5, -2.8 %; the rest is a convention: ANDES's
    GENROU has P_e = T_e (P_e = pout - 2H dw/dt within 5e-6 pu), this bench Kundur's
    P_e = w T_e, which differ by (w - 1) times the inertial power, 3 to 6e-4 pu in the
    spike. With that undone every parameter came out within 0.01 %."""
    clean = _errors(repo, fmus, event, "noise-free")
    droop = "gov.K" if "gov.K" in clean else "gov.R"
    fast = next(name for name in ("gov.T1", "gov.T4", "gov.Ts") if name in clean)
    assert abs(clean[droop]) < 0.005 and abs(clean[fast]) < 0.04
    assert all(abs(e) < 0.01 for name, e in clean.items() if name not in (droop, fast))


def test_the_andes_events_are_what_their_generator_wrote(repo):
    for event in EVENTS:
        truth = json.loads((repo / "experiments" / "electrical" / event / "truth.json").read_text())
        assert truth["andes"] == "2.0.0" and truth["governor_check_pu"] < 2e-4
        assert truth.get("ieeeg1_check_pu", 0.0) < 2e-4  # TG Type I's run as ANDES's IEEEG1


def test_andes_runs_tg_type_i_as_the_ieeeg1_it_equals(repo, fmus, monkeypatch):
    """ANDES has no TG Type I: generate.py runs it as the IEEEG1 it equals between its
    limits (tgtypei_as_ieeeg1), but for a 1 ms steam chest. Driven by ANDES's speed, our
    IEEEG1 bench with the mapped parameters gives ANDES's governor output exactly, our
    TG Type I bench within the tolerance measured for that lag (and it is measurable)."""
    pytest.importorskip("andes", reason="andes (the test extra) runs the grid; without it no TG Type I event")
    monkeypatch.syspath_prepend(str(repo / "experiments" / "electrical"))
    generate = importlib.import_module("generate")
    monkeypatch.setattr(generate, "DURATION", 20.0)  # 10 s after the event: its fast part, a third of the time
    event = next(e for e in generate.EVENTS if e.governor == "TGTypeI")
    checks = generate.governor_check(event, generate.andes_run(event), fmus["FrequencyInput"].parent)
    assert checks["ieeeg1_check_pu"] < 1e-6
    assert 1e-5 < checks["governor_check_pu"] < generate.TOLERANCE["TGTypeI"]


def test_generated_recorded_frequency_benches_have_electrical_power(repo, tmp_path):
    from rapid_cosim.compiler import build_models
    from rapid_cosim.diagnose.catalogue import write_bench

    package = tmp_path / "iGrGen"
    shutil.copytree(repo / "modelica" / "iGrGen", package)
    write_bench(package, ["deadband"], "iGrGen.Diagnosed.FrequencyInputGGOV1Deadband",
                base="iGrGen.TestBenches.FrequencyInputGGOV1")
    (fmu,) = build_models(["iGrGen.Diagnosed.FrequencyInputGGOV1Deadband"], package=package,
                          fmu_dir=tmp_path / "fmus", log=lambda *_: None)
    f, rocof = _event(T)
    run = Simulator(fmu.fmu).simulate({"mach.H": 6.5, "f_nom": F_NOM}, output_times=T, input_time=T,
                                      inputs={"f_dev": f}, outputs=["pm", "pe"])
    assert np.max(np.abs(run["pe"] - run["pm"])) > 0.02  # the machine is in the generated bench


def test_an_estimated_inertia_is_pointed_to_the_generators_record(repo, fmus, tmp_path):
    """A governor record has no field for H: export names the GENROU field it goes in."""
    from rapid_cosim.exchange import ExchangeWarning

    folder = repo / "experiments" / "electrical" / "tgov1_on"
    fit = rc.calibrate([_variant(folder, "H estimated")], method="ms", seed=1, archive=tmp_path / "run.h5",
                       source=ModelSource(fmu_dir=fmus["FrequencyInput"].parent))
    h = fit.parameters["mach.H"]
    with pytest.warns(ExchangeWarning, match=rf"H = {h:.4g} s as CON\(J\+4\).*'GENROU'"):
        written = rc.export(tmp_path / "run.h5", tmp_path / "unit.dyr")
    assert written.model == "TGOV1" and "mach.H" not in written.text
    with pytest.warns(ExchangeWarning, match=r"H = [\d.]+ s as 'h'.*genrou"):
        rc.export(tmp_path / "run.h5", tmp_path / "unit.dyd", mva=900.0)


@pytest.mark.parametrize("kind", ["H fixed", "H estimated"])
def test_a_structure_keeps_the_events_machine(repo, kind):
    """Structure selection swaps the governor, not the machine: H stays as the event gave it."""
    from rapid_cosim.structures.structure import Structure

    exp = _variant(repo / "experiments" / "electrical" / "tgov1_on", kind)
    swapped = Structure.load(repo / "experiments" / "structures" / "IEEEG1.toml").experiment(exp)
    assert swapped.model == "iGrGen.TestBenches.FrequencyInputIEEEG1" and "pe" in swapped.outputs
    if kind == "H fixed":
        assert swapped.fixed["mach.H"] == 6.5
    else:
        assert {s.name: (s.min, s.max) for s in swapped.estimate}["mach.H"] == (2.0, 12.0)


def test_structure_selection_reads_an_events_electrical_power_as_its_mechanical(repo, fmus, tmp_path):
    """TG Type I, TGOV1 and IEEEG1 on tgov1_on's P_e and on its P_m (mechanical.csv, the
    same noise draw): the same verdict and the same structures within the threshold. With
    the ROCOF step one sample early (before c42deea) P_e's verdict was "unexplained"."""
    import sys

    from rapid_cosim.calibration import RunOptions
    from rapid_cosim.structures.select import select_structure

    sys.path.insert(0, str(repo / "benchmarks"))
    from electrical_study import candidate_structures, variant

    folder = repo / "experiments" / "electrical" / "tgov1_on"
    verdicts = [select_structure(candidate_structures(), [variant(folder, kind)], workdir=tmp_path / kind[:3],
                                 options=RunOptions(method="ms", seed=1), source=ModelSource(fmu_dir=fmus["FrequencyInput"].parent),
                                 log=lambda *_: None) for kind in ("P_e, H fixed", "P_m recorded")]
    assert verdicts[0].structure == verdicts[1].structure != "unexplained"
    assert set(verdicts[0].candidates) == set(verdicts[1].candidates) and "TGOV1" in verdicts[0].candidates


def test_the_adequacy_null_of_electrical_power_carries_the_rocofs_noise(repo):
    """The residual of a correct model of P_e holds the recorder's noise and the derived
    ROCOF's; the null's replicates must hold both, whitened alike: variance ratio 1 (0.82
    with the recorder's noise alone)."""
    from rapid_cosim.diagnose.null import replicates_for
    from rapid_cosim.structures.structure import Structure
    from rapid_cosim.noise import campaign_noise
    from rapid_cosim.noise.estimate import NoiseFit

    exp = _variant(repo / "experiments" / "electrical" / "tgov1_on", "H fixed")
    # the noise model taken as known: draws from its likelihood would add the estimate's own
    # uncertainty (a mean ratio of 1.05), which is not what this test is about
    fits = {name: NoiseFit.known(fit.model, fit.tests) for name, fit in campaign_noise([exp]).items()}
    whitened = Structure.load(repo / "experiments" / "structures" / "TGOV1.toml").experiment(exp, fits[exp.name].model)
    ratios = replicates_for([whitened], fits, 200).statistics(None, [])[exp.name][0]
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.05)
