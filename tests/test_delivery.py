"""The delivered record is the model that was fitted (issue 40).

For every standard structure and optional part, a calibration through the path a user
runs (``rc.calibrate``, then ``rc.export`` to ``.dyr`` and ``.dyd``) is read back and
simulated as PSS/E and PSLF read it, by this test's own composition (the test's source
and operating point, every value the record states, IEEEG1's K3 as stated, the bench's
defaults for what the record has no field for), and must give the fitted model's own
simulation on the same recording to 1e-9 pu. The old defect (IEEEG1's ``K3_rest`` not
reaching the writer, so K3 was written at its default 0.3) is injected and refused; a
record on file whose stages do not sum to one is played back with its own K3.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from rapid_cosim.errors import DeliveryError, ParameterError
from rapid_cosim.exchange import read_record
from rapid_cosim.simulator import Simulator
from rapid_cosim.compiler.source import ModelSource

TOLERANCE_PU = 1e-9
STEP = {"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 5.0, "src.t_return": 25.0}
IEEEG1_SINGLE_REHEAT = {"gov.PMAX": 1.0, "gov.PMIN": 0.0, "gov.T1": 0.001, "gov.T2": 0.0, "gov.K3_rest": 1.0,
                        "gov.K5": 0.0, "gov.K7": 0.0}
IEEEG1_ESTIMATE = {"gov.K": {"min": 8.0, "max": 50.0}, "gov.K1": {"min": 0.05, "max": 0.6}}
RATES = {"gov.Uo": {"min": 0.001, "max": 1.0, "scale": "log", "start": 0.012},  # near the plant's: they bind
         "gov.Uc": {"min": -1.0, "max": -0.001, "start": -0.025}}
GGOV1_FIXED = {"gov.Tpelec": 1.0, "gov.Vmax": 1.0, "gov.Vmin": 0.15, "gov.Tact": 0.5, "gov.Kturb": 1.5,
               "gov.Wfnl": 0.2, "gov.Tc": 0.0, "gov.Ldref": 1.0, "gov.Kimw": 0.0}
GGOV1_ESTIMATE = {"gov.Kpgov": {"min": 1.0, "max": 40.0, "scale": "log"}, "gov.Tb": {"min": 0.05, "max": 10.0}}

# case -> (bench, fixed, estimate, the plant's values of the estimated parameters)
CASES = {
    "TGOV1": ("TGOV1", {"gov.VMAX": 0.95, "gov.VMIN": 0.0, "gov.T2": 2.0, "gov.T3": 6.0, "gov.Dt": 0.1},
              {"gov.R": {"min": 0.02, "max": 0.12}, "gov.T1": {"min": 0.05, "max": 3.0}},
              {"gov.R": 0.06, "gov.T1": 0.5}),
    "IEEEG1, K3 from K3_rest, rates wide": ("IEEEG1", IEEEG1_SINGLE_REHEAT, IEEEG1_ESTIMATE,
                                            {"gov.K": 20.0, "gov.K1": 0.3}),
    "IEEEG1, K3 from K3_rest, rates binding and estimated": (
        "IEEEG1", IEEEG1_SINGLE_REHEAT, {**IEEEG1_ESTIMATE, **RATES},
        {"gov.K": 20.0, "gov.K1": 0.3, "gov.Uo": 0.01, "gov.Uc": -0.02}),
    "IEEEG1, K3 stated (K3_rest 0), stages not summing to one": (
        "IEEEG1", {**IEEEG1_SINGLE_REHEAT, "gov.K3_rest": 0.0, "gov.K3": 0.5}, IEEEG1_ESTIMATE,
        {"gov.K": 20.0, "gov.K1": 0.3}),
    "IEEEG1, three stages from K3_rest, lead-lag": (
        "IEEEG1", {**IEEEG1_SINGLE_REHEAT, "gov.K5": 0.3, "gov.T6": 1.5, "gov.T1": 0.5, "gov.T2": 1.0},
        IEEEG1_ESTIMATE, {"gov.K": 20.0, "gov.K1": 0.3}),
    "IEEEG1, three stages stated": (
        "IEEEG1", {**IEEEG1_SINGLE_REHEAT, "gov.K3_rest": 0.0, "gov.K3": 0.4, "gov.K5": 0.3, "gov.T6": 1.5},
        IEEEG1_ESTIMATE, {"gov.K": 20.0, "gov.K1": 0.3}),
    **{f"GGOV1, Rselect {rs}, Flag {fl}": ("GGOV1", {**GGOV1_FIXED, "gov.Rselect": float(rs), "gov.Flag": float(fl),
                                                      **({"gov.R": 0.0} if rs == 0 else {})},
                                           GGOV1_ESTIMATE, {"gov.Kpgov": 10.0, "gov.Tb": 0.5})
       for rs in (1, -1, 0) for fl in (1, 0)},
    "HYGOV": ("HYGOV", {"gov.GMAX": 1.0, "gov.GMIN": 0.0, "gov.Tf": 0.05, "gov.Tg": 0.5, "gov.VELM": 0.2,
                        "gov.At": 1.2, "gov.qNL": 0.08, "gov.Dturb": 0.3, "gov.r": 0.3, "gov.Tr": 5.0},
              {"gov.R": {"min": 0.02, "max": 0.12}, "gov.TW": {"min": 0.1, "max": 4.0}},
              {"gov.R": 0.05, "gov.TW": 1.2}),
    "GAST": ("GAST", {"gov.VMAX": 1.0, "gov.VMIN": 0.0, "gov.AT": 1.0, "gov.KT": 2.0, "gov.T3": 3.0, "gov.T2": 0.1},
             {"gov.R": {"min": 0.02, "max": 0.12}, "gov.T1": {"min": 0.2, "max": 3.0}}, {"gov.R": 0.05, "gov.T1": 0.5}),
    **{f"{m} with its deadband estimated ({m}D)": (
        m, {"TGOV1": {"gov.T2": 2.0, "gov.T3": 6.0}, "IEEEG1": IEEEG1_SINGLE_REHEAT,
            "HYGOV": {"gov.Dturb": 0.3, "gov.TW": 1.2}}[m],
        {("gov.K" if m == "IEEEG1" else "gov.R"): {"min": 8.0, "max": 50.0} if m == "IEEEG1" else {"min": 0.02, "max": 0.12},
         "gov.db": {"min": 0.0, "max": 0.002, "start": 0.0005}},
        {("gov.K" if m == "IEEEG1" else "gov.R"): 20.0 if m == "IEEEG1" else 0.05, "gov.db": 0.0008})
       for m in ("TGOV1", "IEEEG1", "HYGOV")},
}
DEADBAND_LAYOUTS = ("TGOV1D", "IEEEG1D", "HYGOVD")  # no PSLF layout: a .dyd is refused, the .dyr carries it


def _calibrated(fmus, folder, case: str):
    """A short calibration of the case's synthetic staged test: its fit and experiment."""
    import rapid_cosim as rc
    from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment

    bench, fixed, estimate, plant = CASES[case]
    fixed = {**STEP, **fixed}
    t, y = synthesize(fmus[f"StagedTest{bench}"], {**fixed, **plant}, duration=40.0,
                      noise=NoiseModel(white_sigma=0.0005), rng=np.random.default_rng(3))
    config = write_experiment(folder / "test", model=f"iGrGen.TestBenches.StagedTest{bench}", time=t, values=y,
                              fixed=fixed, estimate=estimate)
    fit = rc.calibrate(config, "nm", archive=folder / "run.h5", options={"nm": {"max_fev": 12}})
    return fit, fit.inputs.experiments[0]


def _as_read(record, exp) -> dict[str, float]:
    """What a grid simulator runs: the test's source and operating point, and every value
    the record states (IEEEG1's K3 as stated); nothing else of the fit."""
    params = {k: v for k, v in exp.fixed.items() if not k.startswith("gov.") or k == "gov.p_ref"}
    params.update({f"gov.{k}": v for k, v in record.values.items() if k != "K3_rest"})
    if record.block == "IEEEG1":
        params["gov.K3_rest"] = 0.0
    return params


@pytest.mark.parametrize("case", list(CASES))
def test_the_record_read_back_simulates_what_was_fitted(fmus, tmp_path, case):
    import rapid_cosim as rc

    fit, exp = _calibrated(fmus, tmp_path, case)
    sim = Simulator(fmus[f"StagedTest{CASES[case][0]}"])
    t = exp.windowed_data().time
    fitted = fit.inputs.problem.parameters_for(fit.x, 0)
    y_fit = sim.simulate(fitted, output_times=t, outputs=["pm"])["pm"]
    for kind, options in (("dyr", {}), ("dyd", {"mva": 250.0})):
        if kind == "dyd" and "deadband" in case:
            with pytest.raises(ParameterError, match=r"with a deadband .* has no PSLF layout here: .*the \.dyr's "
                                                     r"(TGOV1D|IEEEG1D|HYGOVD) record carries it"):
                rc.export(fit.archive, tmp_path / f"unit.{kind}", bus=3, machine_id="1", **options)
            assert not (tmp_path / "unit.dyd").exists()
            continue
        delivered = rc.export(fit.archive, tmp_path / f"unit.{kind}", bus=3, machine_id="1", **options)
        assert delivered.reproduction.worst <= TOLERANCE_PU
        record = read_record(tmp_path / f"unit.{kind}")
        y_record = sim.simulate(_as_read(record, exp), output_times=t, outputs=["pm"])["pm"]
        assert np.max(np.abs(y_record - y_fit)) <= TOLERANCE_PU, kind
        for name, value in fit.parameters.items():  # every estimate reached the file as it was
            assert record.values[name.removeprefix("gov.")] == value, name
        if "deadband" in case:
            assert record.model in DEADBAND_LAYOUTS and record.block == CASES[case][0] and record.values["db"] > 0
        if record.model == "IEEEG1" and fitted["gov.K3_rest"] == 1.0:
            rest = 1.0 - fitted["gov.K1"] - fitted["gov.K5"] - fitted["gov.K7"]
            assert record.values["K3"] == pytest.approx(rest, abs=1e-15)


def test_the_old_defect_is_refused_and_nothing_is_written(fmus, tmp_path, monkeypatch):
    """K3_rest dropped on its way to the writer (as before issue 40): K3 goes out at the
    table's 0.3 where the fit ran with 1 - K1; the record read back misses its fit, and
    export refuses it."""
    import rapid_cosim as rc
    from rapid_cosim.exchange.tables import Model

    fit, _ = _calibrated(fmus, tmp_path, "IEEEG1, K3 from K3_rest, rates wide")
    old = property(lambda self: tuple(p for p in self.params if p not in ("p_ref", "Pmwset", "K3_rest")))
    monkeypatch.setattr(Model, "record_params", old)
    with pytest.raises(DeliveryError, match=r"unit\.dyr: not written: the IEEEG1 record, read back, does not "
                                            r"reproduce the fit .* pu on test"):
        rc.export(fit.archive, tmp_path / "unit.dyr")
    assert not (tmp_path / "unit.dyr").exists()
    assert not list(tmp_path.glob(".unit.dyr*"))


def test_a_record_whose_stages_do_not_sum_to_one_is_played_as_written(fmus, repo):
    """A record on file with K1 0.3, K3 0.4, K5 0.3 written out, played on the IEEEG1
    structure (K3_rest = 1): the record's own K3 is played, and the bench's response is
    the published block diagram's with those stages (an independent integration)."""
    from reference_standard import Standard

    from rapid_cosim.exchange import psse_dyr
    from rapid_cosim.structures.structure import Structure

    text = ("7 'IEEEG1' 1 0 0 20.0 0.0 0.0 0.1 1.0 -1.0 1.0 0.0 0.3 0.3 0.0 7.0 0.4 0.0 1.5 0.3 0.0 0.05 "
            "0.0 0.0 /\n")
    (record,), _ = psse_dyr.parse_records(text)
    structure = Structure.load(repo / "experiments" / "structures" / "IEEEG1.toml")
    assert structure.fixed["gov.K3_rest"] == 1.0
    played, x = structure.playing(record.values)
    assert (played.fixed["gov.K3_rest"], played.fixed["gov.K3"], played.fixed["gov.K5"]) == (0.0, 0.4, 0.3)
    assert x == {"gov.K": 20.0, "gov.T3": 0.1, "gov.T4": 0.3, "gov.T5": 7.0, "gov.K1": 0.3}
    params = {**played.fixed, **x, "gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 5.0}
    t = np.arange(0.0, 40.0, 0.05)
    pm = Simulator(fmus["StagedTestIEEEG1"]).simulate(params, output_times=t, outputs=["pm"])["pm"]
    reference = Standard("IEEEG1", {**params, "src.t_return": 1e9}).simulate(t)
    assert np.max(np.abs(pm - reference)) < 2e-5
    # the droop the file states: K (K1 + K3 + K5) = 20 per unit of speed, 0.08 pu at 0.2 Hz
    assert pm[-1] - pm[0] == pytest.approx(20.0 * 0.2 / 50.0, rel=0.02)


def test_the_fleets_check_of_its_own_record_fails_when_the_file_is_not_the_fit(repo, tmp_path, monkeypatch):
    """The old defect injected (K3_rest not reaching the writer) and export's own check
    taken away, as export was before issue 40 (written, never read back): a fleet unit
    identified as IEEEG1 gets a file whose K3 is not the fit's. The fleet reads back the
    record identify wrote, finds it is not the model identify fitted, and fails the unit
    with that reason, so the record never reaches fleet.dyr."""
    import rapid_cosim.calibration.delivery as delivery
    from rapid_cosim.calibration.record import standard_record
    from rapid_cosim.exchange import FORMATS
    from rapid_cosim.exchange.tables import Model
    from rapid_cosim.fleet.spec import load_fleet
    from rapid_cosim.fleet.synthetic import draw_unit, make_fleet
    from rapid_cosim.fleet import Route
    from rapid_cosim.fleet.unit_job import FleetOptions, run_unit

    plan = draw_unit(6, 1)
    assert plan.structure == "IEEEG1" and not plan.record_right  # its record on file fails: it is identified
    spec = make_fleet(tmp_path / "fleet", [6], experiments=repo / "experiments", seed=1, source=ModelSource(fmu_dir=repo / "fmus"))

    def unchecked(inputs, parameters, x, out, *, kind, source, bus, machine_id, mva=None, **_):
        record = standard_record(inputs, parameters, x, source=source)
        written = FORMATS[kind].write_record(out, record.model.name, record.values, bus=bus, machine_id=machine_id,
                                             **({"mva": mva} if kind == "dyd" else {}))
        return delivery.Delivered(written, delivery.Reproduction(None, {}))

    monkeypatch.setattr(Model, "record_params",
                        property(lambda self: tuple(p for p in self.params if p not in ("p_ref", "Pmwset", "K3_rest"))))
    monkeypatch.setattr(delivery, "deliver_record", unchecked)
    entry = load_fleet(spec).units[0]
    result = run_unit(entry, FleetOptions(results=str(tmp_path / "results"), source=ModelSource(package=str(repo / "modelica" / "iGrGen"), fmu_dir=str(repo / "fmus"))))
    assert result.route is Route.FAILED
    assert re.search(r"unit\.dyr: the record written does not reproduce the fit it was written from \(.* pu off",
                     result.error), result.error
    written = read_record(tmp_path / "results" / "units" / entry.name / "unit.dyr")
    assert written.model == "IEEEG1" and written.values["K3"] == 0.3  # the defect, on file
