"""``rapid-cosim check`` (issue 41): what a run would load, loaded and checked first, every
problem at once and each naming its file and key or row; and the bad inputs that used to
be accepted, misreported or reported without a place.

Each broken input is a copy of a bundled example with one thing wrong (two, where the
point is that both are listed)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from rapid_cosim.check import check, kind_of
from rapid_cosim.cli import main

REPO = Path(__file__).resolve().parents[1]


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, f"{old!r} not in {path}"
    path.write_text(text.replace(old, new, 1))


@pytest.fixture
def test1(tmp_path) -> Path:
    return _copy(REPO / "experiments" / "test1", tmp_path / "test1")


@pytest.fixture
def unit(tmp_path) -> Path:
    """The electrical unit (two ANDES events, TGOV1 and IEEEG1 structure files), copied."""
    folder = _copy(REPO / "experiments" / "electrical", tmp_path / "electrical")
    for extra in ("tgov1_on", "tgov1_off", "ieeeg1_on", "tgtypei_rate_on"):
        shutil.rmtree(folder / extra, ignore_errors=True)
    return folder / "unit.toml"


@pytest.fixture
def fleet(tmp_path) -> Path:
    return _copy(REPO / "experiments" / "fleet", tmp_path / "fleet") / "fleet.toml"


def _problems(path, **kw) -> list[str]:
    report = check(path, **kw)
    return [str(p) for p in report.problems]


def _one(path, pattern: str, **kw) -> str:
    problems = _problems(path, **kw)
    assert len(problems) == 1, problems
    assert re.search(pattern, problems[0]), problems[0]
    return problems[0]


def test_the_bundled_examples_pass_and_say_what_a_run_would_do(fleet, unit):
    config = check(REPO / "experiments" / "test1")
    assert config.ok and config.kind == "config"
    text = config.text()
    assert "time base of test1.csv: 900 samples every 100 ms" in text
    assert "estimates R [0.02, 0.12], Ts [0.1, 20]" in text and "stages: pf (10 iterations) then nm" in text
    assert re.search(r"about [\d,]+ simulations", text)
    u = check(unit)
    assert u.ok and u.kind == "unit" and "tgtypei_off_same (held out): time base" in u.text()
    assert "structure IEEEG1: estimates K, T3, T4, T5, K1; with Uo, Uc free too (rate_limit)" in u.text()
    f = check(fleet)
    assert f.ok and f.kind == "fleet" and "unit006: 1 test(s), record on file IEEEG1" in f.text()
    assert [kind_of(p)[0] for p in (REPO / "experiments" / "test1", unit, fleet)] == ["config", "unit", "fleet"]


# --- experiment configs -----------------------------------------------------------------

def test_min_above_max_is_named_by_key(test1):
    _edit(test1 / "config.toml", "min = 0.02, max = 0.12", "min = 0.2, max = 0.12")
    _one(test1, r"config\.toml \[estimate\.\"gov\.R\"\]: min \(0\.2\) must be less than max \(0\.12\)")


def test_five_problems_in_one_config_are_listed_at_once(test1):
    """Issue 56: a misspelt key, a reversed bound, a misspelt key inside an entry, a bad
    value and a wrong column, each independent of the others: all five in one check."""
    config = test1 / "config.toml"
    _edit(config, 'time = "time"\n', 'time = "time"\ndelimter = ","\n')
    _edit(config, "min = 0.02, max = 0.12", "min = 0.2, max = 0.12")
    _edit(config, 'label = "Ts"', 'lable = "Ts"')
    _edit(config, "offset = true", 'offset = "yes"')
    _edit(config, 'outputs = { pm = "pm" }', 'outputs = { pm = "pmx" }')
    problems = _problems(test1)
    expected = [r"\[data\.delimter\]: unknown key 'delimter'.*did you mean 'delimiter'",
                r"\[estimate\.\"gov\.R\"\]: min \(0\.2\) must be less than max",
                r"\[estimate\.\"gov\.Ts\"\.lable\]: unknown key 'lable'",
                r"\[fitness\.offset\]: expected true or false, got 'yes'",
                r"\[data\.outputs\.pm\]: .*no column 'pmx'"]
    assert len(problems) == 5, problems
    for pattern, problem in zip(expected, problems):
        assert re.search(pattern, problem), (pattern, problem)


def test_a_mistake_the_set_aside_causes_is_not_reported(test1):
    """Setting the wrong column aside leaves [data] without outputs: that is the check's
    doing, not the user's, and only the column is said."""
    _edit(test1 / "config.toml", 'outputs = { pm = "pm" }', 'outputs = { pm = "pmx" }')
    _one(test1, r"\[data\.outputs\.pm\]: .*no column 'pmx'")


def test_a_missing_data_file_is_named(test1):
    (test1 / "test1.csv").unlink()
    _one(test1, r"config\.toml \[data\.file\]: .*test1\.csv")


def test_an_unknown_key_gets_a_did_you_mean(test1):
    _edit(test1 / "config.toml", "[fitness]\n", "[fitness]\noffest = true\n")
    _one(test1, r"\[fitness\.offest\]: unknown key 'offest'.*did you mean 'offset'")


def test_a_misspelt_bench_is_named_by_key_with_a_did_you_mean(test1):
    _edit(test1 / "config.toml", 'StagedTest"', 'StagedTst"')
    _one(test1, r"\[experiment\.model\]: unknown model\(s\) iGrGen\.TestBenches\.StagedTst \(did you mean "
                r"iGrGen\.TestBenches\.StagedTest\?\)")


def test_a_parameter_the_bench_lacks_is_named_by_key(test1):
    _edit(test1 / "config.toml", '"gov.Tc"', '"gov.Tcc"')
    _one(test1, r"\[fixed\.\"gov\.Tcc\"\]: model iGrGen\.TestBenches\.StagedTest has no parameter 'gov\.Tcc'")


def test_a_bad_value_in_the_recording_is_named_by_row(test1):
    lines = (test1 / "test1.csv").read_text().splitlines()
    lines[5] = lines[5].split(",")[0] + ",0.6x"
    (test1 / "test1.csv").write_text("\n".join(lines) + "\n")
    _one(test1, r"test1\.csv \[row 6\]: .*'0\.6x' is not a number")


def test_a_decimal_comma_without_its_key_is_named_by_row(test1):
    text = (test1 / "test1.csv").read_text().replace(",", ";").replace(".", ",")
    (test1 / "test1.csv").write_text(text)
    _one(test1, r"test1\.csv \[row 2\]: .*decimal comma: set \[data\] decimal = \",\"")


def test_a_bad_method_is_named(test1):
    _one(test1, r"\[--method\]: unknown method 'pff'", method="pff:10+nm")


# --- units --------------------------------------------------------------------------------

def test_a_holdout_not_among_the_tests_is_named_with_a_did_you_mean(unit):
    _edit(unit, 'holdout = ["tgtypei_off_same"]', 'holdout = ["tgtypei_of_same"]')
    _one(unit, r"unit\.toml \[tests\.holdout\]: 'tgtypei_of_same' is not among the unit's experiments .*did you "
               r"mean 'tgtypei_off_same'\?")


def test_a_config_the_unit_lists_but_lacks_is_named(unit):
    _edit(unit, 'configs = ["tgtypei_on", "tgtypei_off_same"]', 'configs = ["tgtypei_on", "tgtypei_of"]')
    _one(unit, r"unit\.toml \[tests\.configs\]: tgtypei_of: no such experiment config")


def test_a_structure_file_with_min_above_max_names_the_structure_file(unit):
    _edit(unit.parent / "structures" / "TGOV1.toml", '"gov.R" = { min = 0.02, max = 0.12', '"gov.R" = { min = 0.2, '
                                                                                            'max = 0.12')
    _one(unit, r"structures/TGOV1\.toml \[estimate\.\"gov\.R\"\]: min \(0\.2\) must be less than max \(0\.12\)")


def test_a_structure_parameter_its_bench_lacks_names_the_structure_file(unit):
    _edit(unit.parent / "structures" / "IEEEG1.toml", '"gov.T5" =', '"gov.T55" =')
    problems = _problems(unit)
    assert problems and all("structures/IEEEG1.toml [estimate.\"gov.T55\"]" in p for p in problems), problems
    assert "has no settable parameter 'gov.T55'" in problems[0]


def test_a_structure_value_outside_the_models_range_names_the_structure_file(unit):
    _edit(unit.parent / "structures" / "IEEEG1.toml", '"gov.PMAX" = 1.2', '"gov.PMAX" = 3.0')
    _one(unit, r"IEEEG1\.toml \[fixed\.\"gov\.PMAX\"\]: 3 is outside the range .* declares for 'gov\.PMAX': \[0, 2\]")


def _without_section(text: str, name: str) -> str:
    """``text`` without the TOML section ``[name]`` (its header to the next header)."""
    out, skipping = [], False
    for line in text.splitlines(keepends=True):
        if line.startswith("["):
            skipping = line.strip() == f"[{name}]"
        if not skipping:
            out.append(line)
    return "".join(out)


def test_a_section_that_is_not_a_table_is_named(unit):
    """A structure file's [fixed] written as a value, and a unit file's [tests]: each named
    by its file and section (it was a TypeError from deep in the reader)."""
    structure = unit.parent / "structures" / "TGOV1.toml"
    structure.write_text("fixed = 3\n" + _without_section(structure.read_text(), "fixed"))
    _one(unit, r"structures/TGOV1\.toml \[fixed\]: \[fixed\] must be a table \(a section\), got 3")
    other = _copy(REPO / "experiments" / "electrical", unit.parent.parent / "other") / "unit.toml"
    other.write_text("tests = 5\n" + _without_section(other.read_text(), "tests"))
    _one(other, r"unit\.toml \[tests\]: \[tests\] must be a table \(a section\), got 5")


def test_an_mva_out_of_range_is_named(unit):
    _edit(unit, "mva = 900.0", "mva = 900000.0")
    _one(unit, r"unit\.toml \[unit\.mva\]: mva = 900000\.0: the machine's MVA base, a number from 1 to 5000")


def test_every_problem_of_a_unit_is_listed_at_once(unit):
    _edit(unit.parent / "structures" / "TGOV1.toml", '"gov.R" = { min = 0.02, max = 0.12', '"gov.R" = { min = 0.2, '
                                                                                            'max = 0.12')
    _edit(unit.parent / "tgtypei_on" / "config.toml", 'column = "P"', 'column = "POWER"')
    _edit(unit, 'holdout = ["tgtypei_off_same"]', 'holdout = ["tgtypei_off_same", "nope"]')
    problems = _problems(unit)
    assert len(problems) == 2, problems  # the holdout is judged once every config has loaded
    assert any("TGOV1.toml [estimate.\"gov.R\"]" in p for p in problems)
    assert any("tgtypei_on/config.toml [data.outputs.pe]" in p and "'POWER'" in p for p in problems)


def test_a_unit_without_a_held_out_test_is_warned_of_and_still_passes(unit):
    _edit(unit, 'holdout = ["tgtypei_off_same"]', "holdout = []")
    report = check(unit)
    assert report.ok, report.problems
    assert any(line.startswith("warning: no test is held out") for line in report.lines), report.lines


def test_identify_stops_on_the_check_before_any_fit(unit, tmp_path):
    import rapid_cosim as rc
    from rapid_cosim.errors import CheckFailed

    _edit(unit.parent / "structures" / "TGOV1.toml", '"gov.R" = { min = 0.02, max = 0.12', '"gov.R" = { min = 0.2, '
                                                                                            'max = 0.12')
    with pytest.raises(CheckFailed, match=r"1 problem\(s\), nothing was run:\n  .*TGOV1\.toml \[estimate"):
        rc.identify(unit, workdir=tmp_path / "work", report=False, log=lambda *_: None)
    assert not (tmp_path / "work" / "explanation").exists()


# --- fleets -------------------------------------------------------------------------------

def test_a_glob_naming_no_unit_is_named(fleet):
    _edit(fleet, 'units = ["units/*"]', 'units = ["unit/*"]')
    _one(fleet, r"fleet\.toml \[fleet\.units\]: 'unit/\*' names no unit folder")


def test_an_unreadable_record_on_file_is_named_by_line(fleet):
    (fleet.parent / "units" / "unit003" / "record.dyr").write_text("103 'HYGOV' 1 0.05 oops /\n")
    _one(fleet, r"unit003/record\.dyr \[line 1\]: HYGOV takes 12 values, the record has 2")


def test_a_record_whose_model_has_no_structure_is_named(fleet):
    structures = fleet.parent / "units" / "unit003" / "unit.toml"
    _edit(structures, '"structures/HYGOV.toml"', '"structures/TGOV1.toml"')
    _one(fleet, r"unit003/unit\.toml \[structures\.files\]: the record on file .* is HYGOV, and the unit's structures "
                r"\(TGOV1, IEEEG1, GGOV1, TGOV1\) have none")


# --- the CLI -------------------------------------------------------------------------------

def test_the_cli_lists_every_problem_and_exits_2(unit, capsys):
    _edit(unit, "mva = 900.0", "mva = 0.0")
    _edit(unit.parent / "structures" / "IEEEG1.toml", '"gov.PMAX" = 1.2', '"gov.PMAX" = 3.0')
    assert main(["check", str(unit)]) == 2
    out = capsys.readouterr().out
    assert "1 problem(s)" in out and "[unit.mva]" in out  # the unit file stops the rest: it says what to load
    assert main(["check", str(REPO / "experiments" / "test1")]) == 0


def test_show_names_a_config_as_not_an_archive(capsys):
    assert main(["show", str(REPO / "experiments" / "test1" / "config.toml")]) == 2
    err = capsys.readouterr().err
    assert "config.toml: not an archive (the HDF5 file a run writes" in err and "damaged" not in err


def test_simulate_refuses_a_stop_time_before_the_start(capsys):
    assert main(["simulate", "iGrGen.TestBenches.StagedTest", "--stop-time", "-5"]) == 2
    assert "stop_time -5 s must be after start_time 0 s" in capsys.readouterr().err


def test_diagnose_with_every_test_held_out_says_so(test1, tmp_path, capsys):
    """Nothing left to fit on: the user's error, naming --holdout, before any fit (it was a
    ValueError's traceback)."""
    assert main(["diagnose", str(test1), "--holdout", "test1", "--results", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert "[--holdout]: every experiment is held out (test1): keep at least one to fit on" in err
    assert not (tmp_path / "d").exists()


def test_a_warning_said_many_times_is_printed_once_with_its_count(monkeypatch, capsys):
    """A PMU-style recording's STAT-mask warning came once per worker and candidate (about
    50 times, each with the source line under it): the CLI says each warning once, as a
    sentence, and how often it recurred when the command ends."""
    import argparse
    import importlib
    import warnings

    cli_main = importlib.import_module("rapid_cosim.cli.main")  # the module: rapid_cosim.cli.main is its function

    def command(args):
        for _ in range(3):
            warnings.warn("frames flagged invalid in unit.csv are masked", UserWarning)
        warnings.warn("another cause", UserWarning)
        return 0

    parser = argparse.ArgumentParser()
    parser.set_defaults(func=command, command="identify")
    monkeypatch.setattr(cli_main, "build_parser", lambda: parser)
    assert cli_main.main([]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: frames flagged invalid in unit.csv are masked") == 1
    assert err.count("warning: another cause") == 1
    assert "warning said 3 times: frames flagged invalid" in err and "warnings.warn(" not in err


def test_a_decimal_comma_in_toml_and_a_data_file_given_as_a_config_are_named(tmp_path, test1):
    """Issue 56: TOML's own words ('Expected newline...') did not say what was wrong."""
    unit = tmp_path / "u.toml"
    unit.write_text('[unit]\nname = "u"\nmva = 400,0\n')
    _one(unit, r"line 3.*\n.*3 \| mva = 400,0\n.*a decimal comma: TOML numbers take a point")
    _one(test1 / "test1.csv", r"this looks like a data file \(a header of columns\), not a TOML file")
