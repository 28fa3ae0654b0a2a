"""A diagnosis that knows its limits: the adequacy check, materiality, and the verdicts
``unexplained`` and ``<effect> + unexplained remainder``.

The synthetic campaigns are :mod:`rapid_cosim.diagnose.study`'s; the out-of-catalogue
plants are its ``FOREIGN`` ones (a sagging boiler, a non-linear valve curve)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from rapid_cosim.diagnose.candidates import CandidateFit, CandidateSpec, ExperimentResiduals
from rapid_cosim.diagnose.catalogue import NONE
from rapid_cosim.diagnose.limits import check_material
from rapid_cosim.diagnose.materiality import MIN_GAP_SHARE, gap_share, size_share
from rapid_cosim.diagnose.selection import NoiseFloor, Verdict
from rapid_cosim.noise import NoiseFit, RecorderNoise
from rapid_cosim.diagnose.study import CAMPAIGN, draw_case, run_case
from rapid_cosim.diagnose.workflow import DiagnoseOptions
from rapid_cosim.compiler.source import ModelSource


def _residuals(r, name="t"):
    t = np.arange(r.size) * 0.2
    return ExperimentResiduals(name, t, r, float(np.sum(r ** 2)), 0.0, r.size)


def _floor(sigma: float) -> NoiseFloor:
    return NoiseFloor(NoiseFit.known(RecorderNoise(sigma, (), 0.2)))


def test_materiality_measures_size_from_off_to_material():
    assert size_share("deadband", {"db.db": 0.0075}) == pytest.approx(0.25)
    # rates on a log scale: 0.2 pu/s is off, 0.01 material; sqrt(0.2 * 0.01) is half way
    assert size_share("rate_limit", {"gov.rate_open": np.sqrt(0.002), "gov.rate_close": 0.2}) == pytest.approx(0.5)
    floor = {"t": _floor(1.0)}
    before = {"t": _residuals(np.full(100, np.sqrt(5.0)))}  # gap sqrt(5 - 1) = 2
    after = {"t": _residuals(np.full(100, np.sqrt(2.0)))}  # gap 1
    assert gap_share(before, after, floor) == pytest.approx(0.5)


@pytest.mark.parametrize("foreign", ["boiler_dip", "valve_curve"])
def test_an_effect_outside_the_catalogue_is_unexplained(study, tmp_path, foreign):
    work, package, fmu_dir = study
    case = draw_case(foreign, 1, source=ModelSource(package=package, fmu_dir=fmu_dir))
    d = run_case(case, tmp_path, options=DiagnoseOptions(write_model=False), source=ModelSource(package=package, fmu_dir=fmu_dir)).diagnosis
    record = json.loads(json.dumps(d.to_json()))
    assert record["effect"] == "unexplained", record["reason"]
    assert record["effects"] == [] and record["adequate"] is False
    assert record["unexplained"]["where"]["summary"]
    assert set(record["adequacy"]["after"]["tests"]) == {f"step{k + 1}" for k in range(len(CAMPAIGN))}
    assert "no catalogue model does" in record["reason"]


def test_a_detectable_but_immaterial_deadband_leaves_the_verdict_none():
    """The issue's case, built from residuals: a 2 mHz deadband (7 % of the catalogue's
    material 30 mHz) that the criterion preferred but that moves the RMSE by a hair. An
    engineer would not act on it, so the verdict falls back to ``none``; the same fit
    removing most of a visible gap is named."""
    rng = np.random.default_rng(7)
    floor = {"t": _floor(1e-3)}
    noise = 1e-3 * rng.standard_normal(400)
    structure = 1.5e-3 * np.sin(np.arange(400) / 15.0)

    def context(after_structure):
        base = CandidateFit(CandidateSpec(), Path("base.h5"), "m", {}, 2, 1.0, 1)
        fit = CandidateFit(CandidateSpec(("deadband",)), Path("db.h5"), "m", {"db.db": 0.002}, 3, 1.0, 1)
        tests = {id(base): {"t": _residuals(noise + structure)},
                 id(fit): {"t": _residuals(noise + after_structure)}}
        ctx = SimpleNamespace(fits={"none": base, "deadband": fit}, noise=floor,
                              training=[SimpleNamespace(fixed={})], tests=lambda f: tests[id(f)])
        return ctx, base, fit

    ctx, base, fit = context(0.98 * structure)
    chosen, verdict, report = check_material(ctx, base, fit, Verdict("deadband", ["deadband"], reason="ΔBIC 10.8"))
    assert chosen is None and verdict.effect == NONE and verdict.effects == []
    assert report["deadband"]["material"] is False
    assert report["deadband"]["size_share"] == pytest.approx(0.002 / 0.03, abs=0.01)
    assert "detectable but immaterial" in verdict.said
    ctx, base, fit = context(0.1 * structure)
    chosen, verdict, report = check_material(ctx, base, fit, Verdict("deadband", ["deadband"], reason="ΔBIC 40"))
    assert chosen is fit and verdict.effects == ["deadband"] and report["deadband"]["gap_share"] > MIN_GAP_SHARE


def test_misfit_locations_name_the_phase_and_the_scaling(study, tmp_path):
    work, package, fmu_dir = study
    case = draw_case("valve_curve", 2, source=ModelSource(package=package, fmu_dir=fmu_dir))
    d = run_case(case, tmp_path, options=DiagnoseOptions(write_model=False, max_effects=1, candidates=("delay",)),
                 source=ModelSource(package=package, fmu_dir=fmu_dir)).diagnosis
    where = d.adequacy.unexplained["where"]
    assert where["flagged"], where
    assert max(where["phases"].values()) > 1.5
