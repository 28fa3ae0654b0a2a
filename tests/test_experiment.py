"""rapid_cosim.experiment: config files, their errors, and joint problems."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rapid_cosim.errors import ConfigError, DataError
from rapid_cosim.experiment import load_experiment
from rapid_cosim.fitting.problem import build_problem
from rapid_cosim.simulator import ParameterInfo

GOOD = """\
[experiment]
model = "iGrGen.TestBenches.StagedTest"
description = "MCR 60 %, df = -200 mHz"

[data]
file = "rec.csv"
time = "time"
outputs = { pm = "pm" }

[fixed]
"gov.p_ref" = 0.6
"src.df" = -0.2
"src.t_step" = 10.0

[estimate]
"gov.R"  = { min = 0.02, max = 0.12, label = "R" }
"gov.Ts" = { min = 0.1, max = 20.0, label = "Ts", scale = "linear" }
"meas.offset" = { min = -0.01, max = 0.01, per_experiment = true }

[fitness]
window = [0.0, 20.0]
weights = { pm = 1.0 }
offset = true
noise = "pre-step"
pre_step_end = 10.0

[simulation]
stop_time = 20.0
output_interval = 0.02
timeout = 10.0
"""

INFO = {n: ParameterInfo(n, min=lo, max=hi, start=s) for n, lo, hi, s in [
    ("gov.R", 0.001, 1.0, 0.05), ("gov.Ts", 0.01, 100.0, 1.0), ("gov.p_ref", 0.0, 1.0, 0.5),
    ("src.df", None, None, 0.0), ("src.t_step", 0.0, None, 1.0), ("meas.offset", -1.0, 1.0, 0.0),
]}


def make(tmp_path: Path, text: str = GOOD, name: str = "test1", n: int = 201) -> Path:
    """An experiment folder with config.toml and a 10 Hz, 20 s recording rec.csv."""
    folder = tmp_path / name
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(len(name))
    t = np.arange(n) * 0.1 + rng.uniform(0, 0.003, n)
    t[0] = 0.0
    pm = 0.6 + 0.001 * rng.standard_normal(n)
    (folder / "rec.csv").write_text("time,pm\n" + "".join(f"{a:.4f},{b:.6f}\n" for a, b in zip(t, pm)))
    (folder / "config.toml").write_text(text)
    return folder / "config.toml"


def edit(old: str, new: str, text: str = GOOD) -> str:
    assert old in text, old
    return text.replace(old, new)


def error(tmp_path, text, **kw) -> ConfigError:
    path = make(tmp_path, text, **kw)
    with pytest.raises(ConfigError) as e:
        load_experiment(path)
    assert e.value.file == str(path)
    return e.value


# --------------------------------------------------------------------------- good

def test_good_config_loads(tmp_path):
    path = make(tmp_path)
    exp = load_experiment(path.parent)  # a folder works too
    assert exp.name == "test1" and exp.model == "iGrGen.TestBenches.StagedTest"
    assert exp.config_text == GOOD and exp.config_path == path
    assert exp.outputs == {"pm": "pm"}
    assert exp.fixed == {"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 10.0}
    assert [(s.name, s.min, s.max, s.label, s.per_experiment) for s in exp.estimate] == [
        ("gov.R", 0.02, 0.12, "R", False), ("gov.Ts", 0.1, 20.0, "Ts", False),
        ("meas.offset", -0.01, 0.01, "meas.offset", True)]
    assert exp.window == (0.0, 20.0) and exp.offset is True and exp.weights == {"pm": 1.0}
    assert exp.noise == "pre-step" and exp.noise_sigma["pm"] == pytest.approx(0.001, rel=0.35)
    assert (exp.simulation.stop_time, exp.simulation.output_interval,
            exp.simulation.timeout) == (20.0, 0.02, 10.0)
    assert len(exp.data) == 201


def test_a_spec_is_read_and_checked_without_its_recording(tmp_path):
    from rapid_cosim.experiment.config import experiment_from
    from rapid_cosim.experiment.spec import experiment_spec

    path = tmp_path / "test1" / "config.toml"  # no recording beside it
    path.parent.mkdir()
    spec = experiment_spec(GOOD, path)
    assert (spec.name, spec.model, spec.outputs, spec.noise, spec.noise_sigma) == (
        "test1", "iGrGen.TestBenches.StagedTest", {"pm": "pm"}, "pre-step", None)
    assert [s.name for s in spec.estimate] == ["gov.R", "gov.Ts", "meas.offset"]
    with pytest.raises(ConfigError, match="'other' is not an output"):  # a setting's mistake, before any read
        experiment_spec(edit('noise = "pre-step"', "noise = { other = 0.1 }"), path)
    with pytest.raises(ConfigError, match="data file not found") as e:
        experiment_from(spec)
    assert "data.file" in str(e.value)
    exp = load_experiment(make(tmp_path))
    assert experiment_from(experiment_spec(GOOD, exp.config_path)).noise_sigma == exp.noise_sigma


def test_defaults(tmp_path):
    text = """
[experiment]
model = "M"
[data]
file = "rec.csv"
outputs = { pm = "pm" }
[estimate]
"gov.R" = { min = 0.02, max = 0.12 }
"""
    exp = load_experiment(make(tmp_path, text, name="minimal"))
    assert exp.name == "minimal" and exp.description == ""
    assert exp.window == (0.0, float(exp.data.time[-1]))
    assert exp.simulation.stop_time == exp.data.time[-1]
    assert exp.simulation.start_time == 0.0
    assert exp.simulation.output_interval == pytest.approx(0.05, rel=0.05)
    assert exp.offset is False and exp.noise is None and exp.noise_sigma is None
    assert exp.estimate[0].label == "gov.R"


def test_unquoted_dotted_keys_mean_the_same_names(tmp_path):
    text = edit('"gov.R"  = { min', "gov.R = { min", edit('"src.df" = -0.2', "src.df = -0.2"))
    exp = load_experiment(make(tmp_path, text))
    assert "src.df" in exp.fixed and exp.estimate[0].name == "gov.R"


def test_noise_as_number_and_table(tmp_path):
    exp = load_experiment(make(tmp_path, edit('noise = "pre-step"', "noise = 0.002")))
    assert exp.noise_sigma == {"pm": 0.002}
    exp = load_experiment(make(tmp_path, edit('noise = "pre-step"', "noise = { pm = 0.003 }")))
    assert exp.noise_sigma == {"pm": 0.003}


# --------------------------------------------------------------------------- bad configs

def test_invalid_toml_shows_the_line(tmp_path):
    e = error(tmp_path, edit('model = "iGrGen.TestBenches.StagedTest"', "model = iGrGen"))
    assert "invalid TOML" in str(e) and "line 2" in str(e) and "model = iGrGen" in str(e)


def test_missing_required_key(tmp_path):
    e = error(tmp_path, edit('model = "iGrGen.TestBenches.StagedTest"\n', ""))
    assert e.key == "experiment.model" and "missing" in str(e)


@pytest.mark.parametrize("old, new, key, hint", [
    ("[fitness]", "[fitnes]", "fitnes", "fitness"),
    ("weights = {", "weigths = {", "fitness.weigths", "weights"),
    ('label = "R" }', 'lable = "R" }', 'estimate."gov.R".lable', "label"),
])
def test_unknown_key_suggests(tmp_path, old, new, key, hint):
    e = error(tmp_path, edit(old, new))
    assert e.key == key and f"did you mean '{hint}'" in str(e)


@pytest.mark.parametrize("bounds, word", [
    ("min = 0.12, max = 0.02", "must be less than max"),
    ("min = 0.05, max = 0.05", "must be less than max"),
])
def test_inverted_or_equal_bounds(tmp_path, bounds, word):
    e = error(tmp_path, edit("min = 0.02, max = 0.12", bounds))
    assert e.key == 'estimate."gov.R"' and word in str(e)
    assert str(e).startswith(str(tmp_path / "test1" / "config.toml"))


@pytest.mark.parametrize("bounds, key", [
    ('min = "0.02", max = 0.12', 'estimate."gov.R".min'),
    ("min = 0.02, max = true", 'estimate."gov.R".max'),
    ("max = 0.12", 'estimate."gov.R".min'),
])
def test_bounds_must_be_numbers(tmp_path, bounds, key):
    assert error(tmp_path, edit("min = 0.02, max = 0.12", bounds)).key == key


def test_log_scale_moves_by_the_logarithm(tmp_path):
    exp = load_experiment(make(tmp_path, edit('scale = "linear"', 'scale = "log"')))
    space = build_problem([exp]).space
    k = space.names.index("gov.Ts")
    lo, hi = space.lower[k], space.upper[k]
    x = np.array(space.from_unit(np.full(space.dim, 0.5)))
    assert x[k] == pytest.approx(np.sqrt(lo * hi))  # the unit midpoint is the geometric mean
    assert space.to_unit(x)[k] == pytest.approx(0.5)


def test_log_scale_needs_a_positive_minimum(tmp_path):
    text = edit('scale = "linear"', 'scale = "log"')
    e = error(tmp_path, text.replace('"gov.Ts" = { min = 0.1', '"gov.Ts" = { min = 0.0'))
    assert e.key == 'estimate."gov.Ts".min' and "min > 0" in str(e)


def test_unknown_scale_is_refused_clearly(tmp_path):
    e = error(tmp_path, edit('scale = "linear"', 'scale = "sqrt"'))
    assert e.key == 'estimate."gov.Ts".scale' and "linear, log" in str(e)


def test_missing_data_file_shows_absolute_path(tmp_path):
    e = error(tmp_path, edit('file = "rec.csv"', 'file = "../elsewhere/rec.csv"'))
    assert e.key == "data.file"
    assert str((tmp_path / "elsewhere" / "rec.csv").resolve()) in str(e)


def test_missing_column_lists_columns_present(tmp_path):
    e = error(tmp_path, edit('outputs = { pm = "pm" }', 'outputs = { pm = "Pm" }'))
    assert e.key == "data.outputs.pm"
    assert "no column 'Pm'" in str(e) and "columns present: pm" in str(e)


def test_missing_time_column_is_a_config_error(tmp_path):
    e = error(tmp_path, edit('time = "time"', 'time = "t"'))
    assert e.key == "data.time" and "columns present: time, pm" in str(e)


@pytest.mark.parametrize("window, word", [
    ("[50.0, 90.0]", "outside the data"),
    ("[-5.0, 10.0]", "outside the data"),
    ("[10.0, 5.0]", "must be before"),
    ("[10.0]", "expected [start, end]"),
])
def test_window_checks(tmp_path, window, word):
    e = error(tmp_path, edit("window = [0.0, 20.0]", f"window = {window}"))
    assert e.key == "fitness.window" and word in str(e)


def test_weights_for_unknown_output(tmp_path):
    e = error(tmp_path, edit("weights = { pm = 1.0 }", "weights = { pmm = 1.0 }"))
    assert e.key == "fitness.weights.pmm" and "did you mean 'pm'" in str(e)


def test_pre_step_noise_needs_pre_step_end(tmp_path):
    e = error(tmp_path, edit("pre_step_end = 10.0\n", ""))
    assert e.key == "fitness.pre_step_end"


def test_stop_time_before_the_last_sample(tmp_path):
    e = error(tmp_path, edit("stop_time = 20.0", "stop_time = 15.0"))
    assert e.key == "simulation.stop_time"


def test_fixed_and_estimated_at_once(tmp_path):
    e = error(tmp_path, edit('"src.t_step" = 10.0', '"src.t_step" = 10.0\n"gov.R" = 0.05'))
    assert e.key == 'estimate."gov.R"' and "both fixed and estimated" in str(e)


def test_bad_data_stays_a_data_error(tmp_path):
    path = make(tmp_path)
    (path.parent / "rec.csv").write_text("time,pm\n0,1\n0.1,oops\n")
    with pytest.raises(DataError) as e:
        load_experiment(path)
    assert e.value.row == 3


# --------------------------------------------------------------------------- parameter info

def test_unknown_parameter_lists_close_matches(tmp_path):
    exp = load_experiment(make(tmp_path, edit('"gov.Ts" = {', '"gov.Tss" = {')))
    with pytest.raises(ConfigError) as e:
        build_problem([exp], INFO)
    assert e.value.key == 'estimate."gov.Tss"' and e.value.file == str(exp.config_path)
    assert "close matches: gov.Ts" in str(e.value)


def test_bound_outside_declared_range(tmp_path):
    exp = load_experiment(make(tmp_path, edit("min = 0.1, max = 20.0", "min = 0.001, max = 20.0")))
    with pytest.raises(ConfigError) as e:
        build_problem([exp], INFO)
    assert e.value.key == 'estimate."gov.Ts"'
    assert "0.001" in str(e.value) and "[0.01, 100]" in str(e.value)


def test_fixed_value_outside_declared_range(tmp_path):
    exp = load_experiment(make(tmp_path, edit('"gov.p_ref" = 0.6', '"gov.p_ref" = 1.6')))
    with pytest.raises(ConfigError) as e:
        build_problem([exp], INFO)
    assert e.value.key == 'fixed."gov.p_ref"' and "1.6" in str(e.value)


def test_parameter_info_accepts_a_good_config(tmp_path):
    assert build_problem([load_experiment(make(tmp_path))], INFO).space.dim == 3


# --------------------------------------------------------------------------- problems

def test_per_experiment_parameters_expand(tmp_path):
    a = load_experiment(make(tmp_path, name="test1"))
    b = load_experiment(make(tmp_path, edit('"src.df" = -0.2', '"src.df" = 0.2'), name="test3"))
    p = build_problem([a, b])
    assert p.space.names == ("gov.R", "gov.Ts", "meas.offset@test1", "meas.offset@test3")
    assert p.labels == ("R", "Ts", "meas.offset@test1", "meas.offset@test3")
    np.testing.assert_array_equal(p.space.lower, [0.02, 0.1, -0.01, -0.01])
    x = np.array([0.05, 3.0, 0.001, -0.002])
    assert p.parameters_for(x, 0) == {"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 10.0,
                                      "gov.R": 0.05, "gov.Ts": 3.0, "meas.offset": 0.001}
    pb = p.parameters_for(x, "test3")
    assert pb["src.df"] == 0.2 and pb["meas.offset"] == -0.002 and pb["gov.R"] == 0.05
    np.testing.assert_allclose(p.x0, [0.07, 10.05, 0.0, 0.0])
    with pytest.raises(ValueError, match="4 dimensions"):
        p.parameters_for(x[:3], 0)


def test_shared_parameter_with_different_bounds_names_both_files(tmp_path):
    a = load_experiment(make(tmp_path, name="test1"))
    b = load_experiment(make(tmp_path, edit("min = 0.02, max = 0.12", "min = 0.03, max = 0.12"),
                             name="test2"))
    with pytest.raises(ConfigError) as e:
        build_problem([a, b])
    assert e.value.key == 'estimate."gov.R"'
    assert e.value.file == str(b.config_path) and str(a.config_path) in str(e.value)
    assert "min = 0.03" in str(e.value) and "0.02" in str(e.value)


def test_shared_parameter_must_be_estimated_everywhere(tmp_path):
    a = load_experiment(make(tmp_path, name="test1"))
    text = edit('"gov.Ts" = { min = 0.1, max = 20.0, label = "Ts", scale = "linear" }\n', "")
    b = load_experiment(make(tmp_path, edit('"src.t_step" = 10.0', '"src.t_step" = 10.0\n"gov.Ts" = 2.0', text),
                             name="test2"))
    with pytest.raises(ConfigError, match="fixed in test2") as e:
        build_problem([a, b])
    assert e.value.file == str(b.config_path) and str(a.config_path) in str(e.value)


def test_experiment_names_must_be_unique(tmp_path):
    a = load_experiment(make(tmp_path / "x", name="test1"))
    b = load_experiment(make(tmp_path / "y", name="test1"))
    with pytest.raises(ConfigError, match="unique") as e:
        build_problem([a, b])
    assert e.value.key == "experiment.name"


def test_nothing_to_estimate(tmp_path):
    text = GOOD.split("[estimate]")[0] + "[fitness]" + GOOD.split("[fitness]")[1]
    with pytest.raises(ConfigError, match="nothing to estimate"):
        build_problem([load_experiment(make(tmp_path, text))])
