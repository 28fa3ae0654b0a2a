"""The calibration study of issue 32 at a small size: the true model on a few effect-free
campaigns, and the study's arithmetic (``make bench-diagnose`` and ``bench-electrical``
run it on 200 draws and more)."""

from __future__ import annotations

import numpy as np
import pytest

from rapid_cosim.diagnose.campaigns import draw_case, write_campaign
from rapid_cosim.diagnose.false_alarms import TruthFit, clopper_pearson, fit_truth, summary, summary_text
from rapid_cosim.diagnose.workflow import DiagnoseOptions
from rapid_cosim.experiment import load_experiment
from rapid_cosim.compiler.source import ModelSource


def _fit(label, p, alarm=False, covered=None):
    return TruthFit(label, p, p, p, min(p.values()), alarm, 1.0, {}, {}, covered or {})


def test_the_summary_reads_uniform_p_values_alarms_and_coverage():
    rng = np.random.default_rng(0)
    fits = [_fit(f"d{k}", {f"t{j}": float(rng.uniform()) for j in range(4)}, alarm=k < 2,
                 covered={"gov.R": k % 10 != 0}) for k in range(200)]
    s = summary(fits)
    assert s["tests"] == 800 and sum(s["p_deciles"]) == 800 and s["ks"]["p"] > 0.01
    assert s["alarms"] == 2 and s["false_alarm_rate"] == 0.01
    lo, hi = s["false_alarm_interval"]
    assert lo < 0.01 < hi < 0.04
    assert s["coverage"]["gov.R"]["covered"] == 180 and s["coverage"]["gov.R"]["share"] == 0.9
    text = summary_text("study", s)
    assert "2/200 = 0.010" in text and "gov.R 180/200 = 0.90" in text and text.count("alarm: d") == 2


def test_clopper_pearson_bounds_hold_their_level():
    assert clopper_pearson(0, 200)[0] == 0.0 and clopper_pearson(200, 200)[1] == 1.0
    lo, hi = clopper_pearson(10, 200)
    assert lo == pytest.approx(0.0243, abs=1e-3) and hi == pytest.approx(0.0899, abs=1e-3)


def test_the_true_model_on_effect_free_campaigns_is_judged_and_its_intervals_read(study, tmp_path):
    """Three effect-free staged campaigns of the study's plants and recorders (seeds
    1000-1002): each test's p-value in (0, 1], the campaign's decision by Holm at 0.01,
    each estimate's 90 % interval around it and read against the plant's value."""
    work, package, fmu_dir = study
    fits = []
    for seed in (1000, 1001, 1002):
        case = draw_case("none", seed, source=ModelSource(package=package, fmu_dir=fmu_dir))
        experiments = [load_experiment(p) for p in write_campaign(case, tmp_path / case.label, source=ModelSource(package=package, fmu_dir=fmu_dir))]
        truth = {k: case.plant[k] for k in ("gov.R", "gov.Ts")}
        fits.append(fit_truth(case.label, experiments[:-1], experiments[-1:], truth, tmp_path / f"fit{seed}",
                              DiagnoseOptions(write_model=False), ModelSource(package, fmu_dir)))
    for f in fits:
        assert len(f.p) == 4 and all(0 < p <= 1 for p in f.p.values())
        assert f.alarm == (f.p_campaign < 0.01)
        assert set(f.covered) == {"gov.R", "gov.Ts"}
        for name, (lo, hi) in f.intervals.items():
            assert lo < f.parameters[name] < hi
        assert 0.8 < f.variance_ratio < 1.25
    s = summary(fits)
    assert s["draws"] == 3 and s["tests"] == 12
