"""The standard governors' bench FMUs (TGOV1, IEEEG1, GGOV1, HYGOV, GAST) against an
independent scipy integration of their published block diagrams, on parameter sets that
engage the limiters, the rate limits, the water-hammer zero, GGOV1's and GAST's low-value
gates, the speed deadbands (a step beyond the band, and one inside it) and a return step;
and each FMU against fmpy's validation."""

from fmpy.validation import validate_fmu
import numpy as np
import pytest
from reference_standard import Standard

from rapid_cosim.simulator import Simulator

CASES = {
    "TGOV1": {
        "down-step": {},
        "valve held at VMAX, then back": {"gov.p_ref": 0.95, "src.t_return": 35.0},
        "valve at VMIN": {"gov.p_ref": 0.05, "src.df": 0.2},
        "damping, lead-lag, return": {"gov.Dt": 0.5, "gov.T2": 1.0, "gov.T3": 5.0, "src.t_return": 40.0},
        "deadband (TGOV1D), damping, return": {"gov.db": 0.0012, "gov.Dt": 0.5, "src.t_return": 40.0},
    },
    "HYGOV": {
        "down-step: the water-hammer dip": {},
        "gate held at GMAX": {"gov.p_ref": 0.9, "gov.GMAX": 0.9},
        "velocity limit, return": {"gov.VELM": 0.01, "gov.r": 0.05, "gov.Tr": 1.0, "src.t_return": 35.0},
        "long water column, up-step": {"gov.TW": 2.5, "gov.Dturb": 1.0, "src.df": 0.2, "src.t_return": 40.0},
        "deadband (HYGOVD), up-step": {"gov.db": 0.0015, "src.df": 0.2, "src.t_return": 40.0},
    },
    "IEEEG1": {
        "down-step": {},
        "rate limits, return": {"gov.Uo": 0.01, "gov.Uc": -0.02, "src.t_return": 35.0},
        "valve held at PMAX": {"gov.p_ref": 0.95},
        "lead-lag and four stages": {"gov.T1": 0.5, "gov.T2": 1.5, "gov.K": 25.0, "gov.K5": 0.4, "gov.K7": 0.1,
                                     "gov.T7": 2.0, "src.df": 0.2},
        "single reheat, the stages summing to one": {"gov.K3_rest": 1.0, "gov.K1": 0.27, "gov.K3": 0.9,
                                                     "gov.K5": 0.0, "gov.T5": 5.0},
        "deadband (IEEEG1D), lead-lag, rate limit": {"gov.db": 0.001, "gov.T1": 0.5, "gov.T2": 1.5,
                                                     "gov.Uo": 0.02, "src.t_return": 35.0},
    },
    "GGOV1": {
        "down-step: the governor holds the gate": {},
        "load limiter takes the gate, return": {"gov.Ldref": 0.66, "src.t_return": 35.0},
        "acceleration limiter takes the gate": {"gov.aset": 0.01, "src.df": 0.2, "src.t_return": 30.0},
        "valve-stroke droop, PID, rate limits, power controller": {
            "gov.Rselect": -1.0, "gov.Kdgov": 0.5, "gov.Ropen": 0.02, "gov.Kimw": 0.01, "gov.Tc": 0.3,
            "gov.Dm": 0.1, "src.t_return": 40.0},
        "deadband": {"gov.db": 0.001, "src.t_return": 40.0},
    },
    "GAST": {
        "down-step": {},
        "temperature limit takes the gate, return": {"gov.p_ref": 0.8, "gov.AT": 0.85, "gov.KT": 3.0,
                                                      "src.t_return": 35.0},
        "valve held at VMAX": {"gov.p_ref": 0.95},
        "damping, up-step, return": {"gov.Dt": 0.5, "gov.T1": 1.0, "gov.T2": 0.3, "src.df": 0.2,
                                     "src.t_return": 40.0},
    },
}


@pytest.mark.parametrize("model, case", [(m, c) for m, cases in CASES.items() for c in cases])
def test_standard_governor_matches_its_published_diagram(fmus, model, case):
    params = CASES[model][case]
    sim = Simulator(fmus[f"StagedTest{model}"])
    traj = sim.simulate(params, stop_time=60.0, output_interval=0.05)
    expected = Standard(model, params).simulate(traj.time)
    assert np.max(np.abs(traj["pm"] - expected)) < 1e-4
    assert np.ptp(expected) > 0.01  # the step moves the output


def test_the_cases_engage_what_they_name(fmus):
    hyg = Simulator(fmus["StagedTestHYGOV"]).simulate({}, stop_time=20.0, output_interval=0.01,
                                                      outputs=["pm", "gov.g"])
    after = hyg.time > 10.0
    # the power dips below the dispatch while the gate opens: the water-hammer zero
    assert hyg["pm"][after].min() < 0.6 - 1e-3 and hyg["gov.g"][after].max() > hyg["gov.g"][0] + 0.01
    held = Simulator(fmus["StagedTestTGOV1"]).simulate({"gov.p_ref": 0.95}, stop_time=30.0, output_interval=0.05,
                                                      outputs=["gov.x1", "gov.u"])
    assert held["gov.u"].max() > 1.02 and abs(held["gov.x1"].max() - 1.0) < 1e-3
    limited = Simulator(fmus["StagedTestIEEEG1"]).simulate({"gov.Uo": 0.01}, stop_time=30.0, output_interval=0.05,
                                                          outputs=["gov.vl"])
    assert limited["gov.vl"].max() == pytest.approx(0.01, abs=1e-3)
    gate = ["gov.fsr", "gov.fsrn", "gov.fsrt", "gov.fsra"]
    ggov1 = Simulator(fmus["StagedTestGGOV1"])
    load = ggov1.simulate(CASES["GGOV1"]["load limiter takes the gate, return"], stop_time=60.0,
                          output_interval=0.05, outputs=["pm", *gate])
    held = (np.abs(load["gov.fsrt"] - load["gov.fsr"]) < 1e-4) & (load["gov.fsrn"] - load["gov.fsr"] > 1e-4)
    plateau = (load.time > 28.0) & (load.time < 34.0)
    assert held[plateau].all()  # the load limiter holds the gate
    np.testing.assert_allclose(load["pm"][plateau], 0.66, atol=1e-3)  # at Ldref, not the droop's 0.7
    assert load["pm"][-1] == pytest.approx(0.6, abs=5e-3)  # and back after the return
    acc = ggov1.simulate(CASES["GGOV1"]["acceleration limiter takes the gate"], stop_time=40.0,
                         output_interval=0.01, outputs=gate)
    assert ((acc["gov.fsrn"] - acc["gov.fsr"] > 1e-3) & (np.abs(acc["gov.fsra"] - acc["gov.fsr"]) < 1e-4)).any()
    gast = Simulator(fmus["StagedTestGAST"]).simulate(CASES["GAST"]["temperature limit takes the gate, return"],
                                                      stop_time=60.0, output_interval=0.05,
                                                      outputs=["pm", "gov.u", "gov.vt", "gov.fsr"])
    plateau = (gast.time > 25.0) & (gast.time < 34.0)
    assert (gast["gov.u"][plateau] - gast["gov.fsr"][plateau] > 1e-3).all()  # the temperature limit holds the gate
    assert gast["pm"][plateau].max() < 0.8 + 0.2 / 50 / 0.05 - 0.01  # below the droop's 0.88
    assert gast["pm"][-1] == pytest.approx(0.8, abs=5e-3)  # and back after the return


@pytest.mark.parametrize("model, df", [("TGOV1", -0.05), ("IEEEG1", 0.05), ("HYGOV", -0.05), ("GGOV1", 0.05)])
def test_a_step_inside_the_deadband_moves_nothing(fmus, model, df):
    """A 50 mHz step against a band of 0.0012 pu (60 mHz at 50 Hz): the governor holds its
    dispatch; the same step with no band moves it."""
    sim = Simulator(fmus[f"StagedTest{model}"])
    inside = sim.simulate({"gov.db": 0.0012, "src.df": df}, stop_time=40.0, output_interval=0.1)
    plain = sim.simulate({"src.df": df}, stop_time=40.0, output_interval=0.1)
    assert np.max(np.abs(inside["pm"] - 0.6)) < 1e-5
    assert np.max(np.abs(plain["pm"] - 0.6)) > 0.01


@pytest.mark.parametrize("model", list(CASES))
def test_standard_governor_fmus_pass_fmpy_validation(fmus, model):
    for bench in (f"StagedTest{model}", f"FrequencyInput{model}"):
        assert validate_fmu(str(fmus[bench])) == []
