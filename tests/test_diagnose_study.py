"""The discrepancy workflow on synthetic campaigns with a known effect hidden in them.

Realistic recorders (white plus slow noise, jitter, quantisation, a meter offset:
:mod:`rapid_cosim.diagnose.campaigns`), random plants, visible effect sizes, two seeds per
effect and two null campaigns: the correct effect must be named first in at least 90 %
of the cases, ``none`` with an adequate model in every null case, and the gap (RMSE
above the noise floor) must shrink by at least half once the effect is added. ``make
bench-diagnose`` runs more seeds, events and variants, and prints the confusion matrix.
"""

import json
import shutil

import joblib
import pytest

from rapid_cosim.cli import main
from rapid_cosim.diagnose.study import HIDDEN, SINGLE_SIZE, confusion_text, draw_case, run_case, write_campaign
from rapid_cosim.diagnose.workflow import DiagnoseOptions
from rapid_cosim.compiler.source import ModelSource

SEEDS = (1, 2)


@pytest.fixture(scope="module")
def results(study):
    work, package, fmu_dir = study
    cases = [draw_case(t, s, source=ModelSource(package=package, fmu_dir=fmu_dir)) for t in [*HIDDEN, "none"] for s in SEEDS]
    cases.append(draw_case("deadband", 1, SINGLE_SIZE, source=ModelSource(package=package, fmu_dir=fmu_dir)))
    options = DiagnoseOptions(write_model=False, max_effects=1)
    out = joblib.Parallel(n_jobs=2)(
        joblib.delayed(run_case)(c, work / ("single" if c.steps == SINGLE_SIZE else "cases"), options=options,
                                 source=ModelSource(package, fmu_dir)) for c in cases)
    campaigns = [r for r in out if r.case.steps != SINGLE_SIZE]
    print("\n" + confusion_text(campaigns))
    return campaigns, [r for r in out if r.case.steps == SINGLE_SIZE][0]


def test_the_hidden_effect_is_named_first(results):
    campaigns, _ = results
    effects = [r for r in campaigns if r.case.truth != "none"]
    correct = sum(r.correct for r in effects)
    assert correct >= 0.9 * len(effects), [(r.case.label, r.diagnosis.effect, r.diagnosis.named.candidates)
                                           for r in effects if not r.correct]


def test_an_effect_free_campaign_with_slow_recorder_noise_is_none_and_adequate(results):
    campaigns, _ = results
    null = [r for r in campaigns if r.case.truth == "none"]
    assert null and all(r.case.noise.ar1_sigma > 0 and r.case.noise.tau for r in null)  # white plus slow noise
    for r in null:
        assert r.diagnosis.effect == "none" and r.diagnosis.adequate, (r.case.label, r.diagnosis.named.reason,
                                                                       r.diagnosis.adequacy.after.p)


def test_the_gap_shrinks_by_half_once_the_effect_is_added(results):
    campaigns, _ = results
    named = [r for r in campaigns if r.correct and r.case.truth != "none"]
    assert named
    for r in named:
        assert r.gap_shrink >= 0.5, (r.case.label, r.gap_shrink)


def test_one_step_size_cannot_exclude_a_deadband_so_none_carries_it_as_a_caveat(results):
    _, single = results
    d = single.diagnosis.named
    # a deadband cannot beat none decisively on one step size: the verdict is none, with
    # the deadband as a caveat that the data cannot exclude at a material size
    assert d.effect == "none", (d.effect, d.reason)
    assert any(c.startswith("deadband") for c in d.not_excluded), d.not_excluded
    # and it says which test would separate them: another step size than the one in the data
    sep = d.separating_test
    assert sep is not None
    assert abs(sep.test.steps_hz[0]) != pytest.approx(0.2)
    # with the chance it settles the choice once recorded and both refitted, said in the advice
    p = sep.probability
    assert 0.0 <= p <= 1.0 and p == min(sep.probability_if.values())
    assert f"probability {p:.2f}" in sep.words and (p >= 0.9) == sep.found
    assert all(label in sep.words for label in sep.between)


def test_named_effect_is_written_compiled_recalibrated_through_the_cli(study, tmp_path):
    work, package, fmu_dir = study
    own = tmp_path / "iGrGen"
    shutil.copytree(package, own)
    case = draw_case("backlash", 3, source=ModelSource(package=package, fmu_dir=fmu_dir))
    configs = write_campaign(case, tmp_path / "data", source=ModelSource(package=package, fmu_dir=fmu_dir))
    verdict = tmp_path / "verdict.json"
    assert main(["diagnose", *map(str, configs), "--holdout", "step4", "--results", str(tmp_path / "diagnosis"),
                 "--json", str(verdict), "--max-effects", "1", "--package", str(own),
                 "--fmus", str(tmp_path / "fmus"), "--compiler", "embedded"]) == 0
    record = json.loads(verdict.read_text())
    assert {"effect", "ranking", "gap_before", "gap_after"} <= set(record)
    assert record["effect"] == "backlash"
    assert record["model_written"] == "iGrGen.Diagnosed.CalibratedBacklash"
    written = own / "Diagnosed" / "CalibratedBacklash.mo"
    assert written.exists() and "backlash = " in written.read_text()
    assert (tmp_path / "fmus" / "iGrGen.Diagnosed.CalibratedBacklash.fmu").exists()
    before = sum(v["gap"] for v in record["gap_before"].values())
    after = sum(v["gap"] for v in record["gap_after"].values())
    assert after < 0.5 * before
    assert set(record["parameter_intervals"]) >= {"gov.R", "gov.Ts", "gov.backlash"}
    assert (tmp_path / "diagnosis" / "residuals.png").exists()
    assert (tmp_path / "diagnosis" / "diagnosis.md").read_text().startswith("# Discrepancy diagnosis")


def test_a_variant_of_form_is_not_blamed_on_the_documentation(study, tmp_path):
    """A load controller acting on filtered power, T5 as documented: the verdict may name
    the load controller, its variant, or say it cannot tell the variant from a freed
    constant, but never blames the documented T5 alone."""
    work, package, fmu_dir = study
    case = draw_case("load_controller_filtered", 2, source=ModelSource(package=package, fmu_dir=fmu_dir))
    result = run_case(case, tmp_path, options=DiagnoseOptions(write_model=False, max_effects=2), source=ModelSource(package=package, fmu_dir=fmu_dir))
    d = result.diagnosis.named
    assert result.correct and not result.documentation_blamed, (d.verdict, d.candidates, d.reason)


def test_two_hidden_effects_are_both_named_greedily(study, tmp_path):
    work, package, fmu_dir = study
    case = draw_case("rate_limit+load_controller", 1, source=ModelSource(package=package, fmu_dir=fmu_dir))
    result = run_case(case, tmp_path, options=DiagnoseOptions(write_model=False, max_effects=2), source=ModelSource(package=package, fmu_dir=fmu_dir))
    d = result.diagnosis.named
    assert set(d.effects) == {"rate_limit", "load_controller"}, (d.effect, d.effects, d.reason)
    assert result.gap_shrink >= 0.5


def test_following_the_advice_once_settles_a_lag_the_four_tests_leave_ambiguous(study, tmp_path):
    """The loop of ``make bench-advice`` on one invented plant: TG Type I (R 0.048, Ts 2.45 s,
    dispatch 0.6) whose power transducer lags by 0.94 s, recorded by a recorder with white
    and slow noise. The four staged tests leave the lag ambiguous with a rival; the advised
    test, recorded from the plant with fresh noise, must settle it as the advice says it
    will (its stated probability is 0.9 or more)."""
    from rapid_cosim.diagnose.campaigns import CAMPAIGN, Case, write_advised
    from rapid_cosim.diagnose.catalogue import VerdictKind
    from rapid_cosim.diagnose.workflow import diagnose
    from rapid_cosim.experiment import load_experiment
    from rapid_cosim.experiment.synthetic import NoiseModel

    work, package, fmu_dir = study
    source = ModelSource(package, fmu_dir)
    case = Case("measurement_lag", 2, {"gov.R": 0.04805, "gov.Ts": 2.454, "gov.p_ref": 0.6}, {"meas.T": 0.9444},
                CAMPAIGN, NoiseModel(white_sigma=0.0011856, ar1_sigma=0.00046339, offset=0.00064, tau=0.60717,
                                     quantum=2.0 / 65536), "staged", 0.00077)
    options = DiagnoseOptions(write_model=False)
    first = run_case(case, tmp_path, options=options, source=source).diagnosis
    assert first.kind is VerdictKind.AMBIGUOUS, first.named.reason
    sep = first.named.separating_test
    assert "measurement_lag" in sep.between and sep.found and sep.probability >= 0.9
    # what each outcome would mean: a group of rivals no test splits is named as one, the documentation deciding
    for outcome in (*("names " + " or ".join(g) for g in sep.groups), "none ahead",
                    *("the documentation of the unit must decide between them" for g in sep.groups if len(g) > 1)):
        assert outcome in sep.words, sep.words
    exps = [load_experiment(p) for p in sorted((tmp_path / case.label / "data").glob("step*/config.toml"))]
    new = [load_experiment(p) for p in write_advised(case, sep.test, tmp_path / "advised", source=source)]
    assert len(new) == len(sep.test.steps_hz)
    second = diagnose([*exps[:-1], *new], exps[-1:], workdir=tmp_path / "second", options=options, source=source)
    assert second.kind is VerdictKind.NAMED and second.named.effects == ["measurement_lag"], second.named.reason
    assert second.adequate
