"""The validation report: its metrics against what the synthetic tests imply, pass and
fail against the tolerance bands (a correct model passes, another unit's test fails),
the tolerance files and their errors, the delivered record, the noise model, the
diagnosis and the provenance; the page opened in a real headless Chromium, every figure
loaded and every mark shown, and the PDF it prints read back."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess
import tempfile

import numpy as np
import pytest

import rapid_cosim as rc
from rapid_cosim.cli import main
from rapid_cosim.errors import ConfigError
from rapid_cosim.validation.tolerances import DEFAULT_BANDS, METRIC_TERMS, load_tolerances
from rapid_cosim.report.html import validation_page
from rapid_cosim.report.pdf import QUIET
from rapid_cosim.compiler.source import ModelSource

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
NEEDS_CHROMIUM = pytest.mark.skipif(CHROMIUM is None, reason="needs Chromium (Debian package 'chromium'; "
                                    ".ci/run installs it)")
FAST = {"pso": {"n_particles": 12}, "nm": {"max_fev": 60}}

# After loading, count the images that decoded to a real bitmap and the pass/fail marks
# drawn with their colours, and write it in the page.
CHECK = """<script>
window.addEventListener('load', () => {
  const imgs = [...document.images];
  const ok = imgs.filter(i => i.complete && i.naturalWidth > 100 && i.naturalHeight > 100);
  const shown = cls => [...document.querySelectorAll('.mark.' + cls)].filter(
      m => m.offsetWidth > 0 && getComputedStyle(m).backgroundColor !== 'rgba(0, 0, 0, 0)').length;
  const div = document.createElement('div');
  div.id = 'rc-check';
  div.textContent = `images ${ok.length}/${imgs.length} tables ${document.querySelectorAll('table').length} ` +
                    `pass ${shown('pass')} fail ${shown('fail')}`;
  document.body.appendChild(div);
});
</script>"""
CHECKED = re.compile(r'<div id="rc-check">images (\d+)/(\d+) tables (\d+) pass (\d+) fail (\d+)</div>')


@pytest.fixture(scope="module")
def joint_run(repo, fmus, tmp_path_factory):
    folder = tmp_path_factory.mktemp("page")
    rc.calibrate([repo / "experiments/event1", repo / "experiments/test2"], "pso:4+nm", archive=folder / "run.h5",
                 options=FAST, source=ModelSource(fmu_dir=repo / "fmus", package=repo / "modelica/iGrGen"))
    return folder / "run.h5"


TGOV1_FIXED = {"gov.p_ref": 0.6, "src.t_step": 5.0, "gov.VMAX": 0.95, "gov.T3": 6.0}


@pytest.fixture(scope="module")
def tgov1_unit(repo, fmus, tmp_path_factory):
    """A TGOV1 unit (R 0.06, T1 0.5) calibrated on one staged test; held out: the same
    unit on a step the other way, and a test of another unit (R 0.04)."""
    from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment

    work = tmp_path_factory.mktemp("unit")

    def test(name: str, df: float, r: float, seed: int):
        fixed = {**TGOV1_FIXED, "src.df": df}
        t, y = synthesize(fmus["StagedTestTGOV1"], {**fixed, "gov.R": r, "gov.T1": 0.5}, duration=40.0,
                          noise=NoiseModel(white_sigma=0.0008), rng=np.random.default_rng(seed))
        return write_experiment(work / name, model="iGrGen.TestBenches.StagedTestTGOV1", time=t, values=y,
                                fixed=fixed, estimate={"gov.R": {"min": 0.02, "max": 0.12},
                                                       "gov.T1": {"min": 0.1, "max": 2.0}},
                                fitness={"offset": True, "noise": "pre-step", "pre_step_end": 5.0})

    step, step_up, other = test("step", -0.2, 0.06, 1), test("step_up", 0.15, 0.06, 2), test("other", -0.2, 0.04, 3)
    fit = rc.calibrate(step, "nm", archive=work / "run.h5", options={"nm": {"max_fev": 80}},
                       source=ModelSource(fmu_dir=repo / "fmus", package=repo / "modelica/iGrGen"))
    return work, fit, step_up, other


def _page(tgov1_unit, repo, out, **options):
    work, fit, step_up, other = tgov1_unit
    return validation_page(fit.archive, out, heldout=[step_up, other], source=ModelSource(fmu_dir=repo / "fmus", package=repo / "modelica/iGrGen"), **options)


def test_metrics_agree_with_the_fit_and_the_event(joint_run):
    page = validation_page(joint_run)
    assert page.path.exists() and page.n_figures == 2
    event = next(m for m in page.metrics if m.experiment == "event1")
    # the grid settles 0.0714 Hz low: a unit of droop 0.055 on 50 Hz raises pm by 0.026 pu
    assert event.settled_change[0] == pytest.approx(0.0714286 / 50 / 0.055, rel=0.03)
    assert abs(event.settled_error) < 0.02 * event.settled_change[0]
    # near the noise, not at it: R and Ts are shared with a staged test of another plant
    assert 0.9 * event.noise < event.rmse < 1.6 * event.noise
    assert event.peak_error > 2 * event.rmse
    assert event.rise_time[0] is not None and 1.0 < event.rise_time[0] < 15.0
    # the frequency recovers part way after its nadir: the power peaks above its settled change
    assert event.peak_change[0] > 1.1 * event.settled_change[0] and event.time_to_peak[0] is not None
    assert event.settling_time[0] > event.rise_time[0]
    fit = rc.load(joint_run)
    staged = next(m for m in page.metrics if m.experiment == "test2")
    assert staged.rmse > 0 and np.isfinite(fit.fun)
    assert staged.time_to_peak == (None, None)  # a first-order-like rise: no overshoot, no time to peak
    assert page.record.model is None and "2 models" in page.record.note  # two benches: no single record


def test_a_calibrated_unit_passes_and_another_units_test_fails(tgov1_unit, repo, tmp_path):
    page = _page(tgov1_unit, repo, tmp_path / "unit.html")
    by_name = {m.experiment: (m, c) for m, c in zip(page.metrics, page.checks)}
    assert [m.role for m in page.metrics] == ["training", "held out", "held out"]
    for name in ("step", "step_up"):  # the model that made the data: every judged metric in its band
        m, checks = by_name[name]
        assert all(c.passed is not False for c in checks), (name, checks)
        assert sum(c.passed is True for c in checks) >= 5
        # TGOV1 on a 0.2 Hz step: 0.2 / 50 / 0.06 = 0.0667 pu up; 0.15 Hz: 0.05 pu down
    assert by_name["step"][0].settled_change[0] == pytest.approx(0.2 / 50 / 0.06, rel=0.05)
    assert by_name["step_up"][0].settled_change[0] == pytest.approx(-0.15 / 50 / 0.06, rel=0.05)
    m, checks = by_name["other"]  # R 0.04: half as much power again as the model predicts
    failed = {c.metric for c in checks if c.passed is False}
    assert {"rmse", "settled_change", "peak_change"} <= failed
    assert m.settled_change[0] == pytest.approx(0.2 / 50 / 0.04, rel=0.05)
    assert page.passed is False
    text = page.path.read_text()
    assert text.count('class="mark fail"') >= 3 and text.count('class="mark pass"') >= 10
    assert "NERC MOD-027-1" in text and "project&#x27;s own choice" in text  # the bands' source, on the page


def test_a_tolerance_file_sets_the_bands(tgov1_unit, repo, tmp_path, capsys):
    strict = tmp_path / "strict.toml"
    strict.write_text("[validation]\nrmse = { noise = 0.5 }  # no model is better than its noise\n"
                      "settling_time = {}\n")
    tol = load_tolerances(strict)
    assert tol.bands["rmse"] == {"noise": 0.5} and tol.bands["settling_time"] == {}
    assert tol.bands["rise_time"] == DEFAULT_BANDS["rise_time"]  # not named: the default
    work, fit, *_ = tgov1_unit
    out = tmp_path / "strict.html"
    assert main(["report", str(fit.archive), "--out", str(out), "--tolerances", str(strict),
                 "--fmus", str(repo / "fmus")]) == 0
    printed = capsys.readouterr().out
    assert re.search(r"step\s+training\s+FAIL .*outside: RMSE", printed), printed
    assert str(strict) in out.read_text()  # the source of the bands, on the page


@pytest.mark.parametrize("text,found", [
    ("[validation]\nrmse = { noise = 2.0 }\nsettle = { relative = 0.1 }\n",
     r"bad\.toml:3 \[validation\.settle\]: unknown metric 'settle'; allowed: rmse, peak_change"),
    ("[validation]\nrise_time = { relative = 0.1, noise = 3.0 }\n",
     r"bad\.toml:2 \[validation\.rise_time\.noise\]: unknown term 'noise' for rise_time; allowed: relative, seconds"),
    ("[validation]\nsettled_change = { relative = 0.1 }\n\n[validation.peak_change]\nnoise = 3\nrelative = 1.5\n",
     r"bad\.toml:6 \[validation\.peak_change\.relative\]: relative = 1\.5 is outside the allowed range: "
     r"a number > 0 and <= 1"),
    ("[validation]\nrmse = { noise = -1 }\n", r"bad\.toml:2 \[validation\.rmse\.noise\]: noise = -1 is outside"),
    ("[validation]\nrmse = { noise = \"two\" }\n", r"noise = 'two' is outside the allowed range"),
    ("[validation]\nrmse = 2.0\n", r"bad\.toml:2 \[validation\.rmse\]: rmse = 2\.0: give a table of terms"),
    ("[tolerances]\nrmse = { noise = 2 }\n", r"bad\.toml: no \[validation\] table"),
    ("[validation\n", r"bad\.toml: invalid TOML"),
])
def test_a_bad_tolerance_file_is_refused_with_file_line_key_value_and_range(tmp_path, text, found):
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    with pytest.raises(ConfigError, match=found):
        load_tolerances(bad)


def test_a_response_that_never_settles_fails_and_an_undefined_time_is_not_judged():
    import math

    from rapid_cosim.validation.tolerances import Tolerances, judge
    from rapid_cosim.validation.metrics import ValidationMetrics, _moving_mean

    def checks(settling, rise=(10.0, 10.5)):
        m = ValidationMetrics("t", "pm", 0.001, 0.004, (0.066, 0.066), (0.067, 0.066), rise, (None, None), settling,
                              0.0008)
        return {c.metric: c for c in judge(m, Tolerances())}

    assert checks((math.inf, 12.0))["settling_time"].passed is False  # the unit never settles, the model does
    assert checks((12.0, math.inf))["settling_time"].passed is False
    assert checks((math.inf, math.inf))["settling_time"].passed is True
    assert checks((12.0, 14.0))["settling_time"].passed is True  # 2 s: within 20 % of 12 s (2.4 s)
    assert checks((12.0, 15.0))["settling_time"].passed is False
    c = checks((12.0, 12.0), rise=(None, None))
    assert c["rise_time"].passed is None and c["time_to_peak"].passed is None  # not judged, not passed
    assert c["rmse"].band == pytest.approx(max(2 * 0.0008, 0.05 * 0.066))
    assert np.allclose(_moving_mean(np.ones(50), 10), 1.0)  # no padding pulls the ends toward zero


def test_the_bad_file_is_refused_before_any_work_by_the_cli(joint_run, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[validation]\nrmse = { noise = 0 }\n")
    assert main(["report", str(joint_run), "--out", str(tmp_path / "p.html"), "--tolerances", str(bad)]) == 2
    assert "rmse.noise" in capsys.readouterr().err and not (tmp_path / "p.html").exists()


def test_every_default_band_is_a_valid_band_and_the_example_file_states_them(repo):
    for metric, terms in DEFAULT_BANDS.items():
        assert set(terms) <= set(METRIC_TERMS[metric]) and terms
    assert load_tolerances(repo / "docs" / "tolerances.toml").bands == DEFAULT_BANDS


def test_the_unit_section_holds_the_record_noise_diagnosis_and_provenance(tgov1_unit, repo, tmp_path):
    from rapid_cosim.diagnose.adequacy import Adequacy, TestAdequacy
    from rapid_cosim.noise import NoiseFit, RecorderNoise

    work, fit, *_ = tgov1_unit
    adequacy = Adequacy(True, 1.02, 0.62, 0.01, 1000, (TestAdequacy("step", 1.02, 9.5, 0.4, 0.7, 0.62, 0.62,
                                                                    1.01, 400, True),))
    noise = NoiseFit.known(RecorderNoise(0.0008, (), 0.1), ["step"]).to_json()
    diagnosis = tmp_path / "diagnosis.json"
    diagnosis.write_text(json.dumps({"verdict": "none", "reason": "the base model fits to the noise",
                                     "adequate": True, "adequacy": {"before": adequacy.to_json(),
                                                                    "after": adequacy.to_json()},
                                     "noise": {"recorders": [noise]}}))
    page = _page(tgov1_unit, repo, tmp_path / "unit.html", diagnosis=diagnosis, mva=110.0, bus=5, machine_id="2")
    text = page.path.read_text()
    # the records: what rc.export writes, in both formats
    dyr = rc.export(fit.archive, tmp_path / "unit.dyr", bus=5, machine_id="2")
    dyd = rc.export(fit.archive, tmp_path / "unit.dyd", bus=5, machine_id="2", mva=110.0)
    assert page.record.model == "TGOV1" and page.record.dyr == dyr.text and page.record.dyd == dyd.text
    import html

    assert html.escape(dyr.text) in text and html.escape(dyd.text) in text
    origin = {p.name: p.origin for p in page.record.parameters}
    assert origin["gov.R"] == origin["gov.T1"] == "estimated"
    assert origin["gov.VMAX"] == origin["gov.T3"] == "documented"  # fixed in the config
    assert origin["gov.T2"] == origin["gov.Dt"] == "bench default"
    assert origin["gov.eps_v"] == "bench default (no field in the record)"  # a smooth limit's sharpness
    estimated = next(p for p in page.record.parameters if p.name == "gov.R")
    assert estimated.interval[0] < fit.parameters["gov.R"] < estimated.interval[1]
    # the noise fitted to the quiet data: white, near the 0.0008 pu the data were made with
    assert "fitted by REML" in text
    sigma = float(re.search(r"white (\d\.\d+)", text).group(1))
    assert 0.0006 < sigma < 0.0010
    assert "Verdict of" in text and "<b>none</b>" in text and "campaign p = 0.62" in text
    assert "<td>step</td><td>1.02</td><td>1.01</td><td>0.62</td><td>0.62</td>" in text  # the test's p-values
    # provenance: every file's digest, the archive's, the versions
    for name in ("step", "step_up", "other"):
        data = work / name / "data.csv"
        assert hashlib.sha256(data.read_bytes()).hexdigest() in text
    assert hashlib.sha256(fit.archive.read_bytes()).hexdigest() in text
    assert f"numpy {np.__version__}" in text and "fmpy " in text and "casadi " in text


def test_a_held_out_test_must_be_predictable(tgov1_unit, repo, tmp_path):
    work, fit, *_ = tgov1_unit
    with pytest.raises(ConfigError, match="training test"):
        validation_page(fit.archive, tmp_path / "p.html", heldout=[work / "step"], source=ModelSource(fmu_dir=repo / "fmus"))


def test_the_cli_writes_the_page_where_asked(joint_run, tmp_path, capsys):
    out = tmp_path / "unit.html"
    assert main(["report", str(joint_run), "--out", str(out)]) == 0
    text = out.read_text()
    assert text.count('src="data:image/png;base64,') == 2
    assert "http://" not in text and "https://" not in text  # nothing to fetch: it opens offline
    assert "gov.R" in text and "interval" in text
    assert "event1" in capsys.readouterr().out


def test_no_chromium_is_a_clear_error_before_any_work(joint_run, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("RAPID_COSIM_CHROMIUM", str(tmp_path / "no-such-chromium"))
    assert main(["report", str(joint_run), "--out", str(tmp_path / "p.html"), "--pdf"]) == 2
    err = capsys.readouterr().err
    assert "no-such-chromium" in err and "apt-get install chromium" in err
    assert not (tmp_path / "p.html").exists()


def _dom(page) -> tuple[int, ...]:
    checked = page.with_name("checked.html")
    checked.write_text(page.read_text().replace("</body>", CHECK + "\n</body>"))
    with tempfile.TemporaryDirectory() as profile:
        dom = subprocess.run(
            [CHROMIUM, *QUIET, f"--user-data-dir={profile}", "--virtual-time-budget=10000", "--dump-dom",
             checked.as_uri()],
            capture_output=True, text=True, timeout=120).stdout
    found = CHECKED.search(dom)
    assert found, dom[-2000:]
    return tuple(map(int, found.groups()))


@NEEDS_CHROMIUM
def test_the_page_renders_in_headless_chromium_with_every_figure_and_mark(tgov1_unit, repo, tmp_path):
    page = _page(tgov1_unit, repo, tmp_path / "unit.html", mva=110.0)
    loaded, total, tables, passes, fails = _dom(page.path)
    assert total == 3 and loaded == total  # training and both held-out tests
    assert tables == 6  # summary, metrics, bands, parameters, noise, provenance (no diagnosis given)
    text = page.path.read_text()
    assert passes == text.count('class="mark pass"') and fails == text.count('class="mark fail"') and fails >= 3
    from rapid_cosim.report.pdf import screenshot

    png = screenshot(page.path, tmp_path / "top.png", width=800, height=600)
    head = png.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(head[16:20], "big") == 800


@NEEDS_CHROMIUM
def test_the_pdf_is_the_page_printed(tgov1_unit, repo, tmp_path, capsys):
    from pdf_text import pdf_pages

    work, fit, step_up, other = tgov1_unit
    out = tmp_path / "unit.html"
    assert main(["report", str(fit.archive), "--out", str(out), "--pdf", "--holdout", str(step_up), str(other),
                 "--mva", "110", "--fmus", str(repo / "fmus")]) == 0
    pdf = out.with_suffix(".pdf")
    assert f"PDF: {pdf}" in capsys.readouterr().out
    assert pdf.read_bytes()[:5] == b"%PDF-"
    pages = pdf_pages(pdf)
    assert len(pages) >= 3  # tables, records, and the figures from a page of their own
    text = "\n".join(pages)
    squeezed = re.sub(r"\s+", "", text)
    assert "Validation of the calibrated model" in pages[0] and "Error metrics" in pages[0]
    assert "TGOV1" in text and "tgov1" in text and "mva=110.0" in squeezed  # both records
    assert text.count("✓ pass") == out.read_text().count('class="mark pass"')
    assert text.count("✗ fail") == out.read_text().count('class="mark fail"') >= 3
    assert hashlib.sha256(fit.archive.read_bytes()).hexdigest() in squeezed
    assert "file://" not in text  # no browser header or footer (they name the page's address)
    figures = next(i for i, p in enumerate(pages) if "Measured and simulated" in p)
    assert figures > 0 and "Error metrics" not in pages[figures]  # the figures start a page
