"""CSV as recorders export it: delimiter detected or set, decimal comma, BOM, CRLF, a
units row, and refusals that name file, row and value."""

from __future__ import annotations

import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from rapid_cosim.data import MaskedSamplesWarning, load_measurements
from rapid_cosim.data.csv_table import SkippedRowWarning
from rapid_cosim.errors import ConfigError, DataError
from rapid_cosim.experiment import load_experiment

REPO = Path(__file__).resolve().parents[1]
TEST1 = REPO / "experiments" / "test1"

# One recording: a negative value, an exponent, a blank (missing) sample and a nan.
COMMA = "time,pm,f\n0.0,0.6,50.0\n0.02,0.61,49.98\n0.04,,49.97\n0.06,-1.5e-3,nan\n0.08,0.625,49.95\n"


def dialect(text: str, delimiter: str, decimal: str = ".") -> str:
    """The comma-delimited ``text`` written with another delimiter and decimal separator."""
    return "".join(delimiter.join(cell.replace(".", decimal) for cell in line.split(",")) + "\n"
                   for line in text.splitlines())


def write(path: Path, text: str, bom: bool = False, crlf: bool = False) -> Path:
    data = text.replace("\n", "\r\n") if crlf else text
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + data.encode("utf-8"))
    return path


def load(path: Path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MaskedSamplesWarning)
        return load_measurements(path, **kw)


def assert_same(a, b):
    np.testing.assert_array_equal(a.time, b.time)
    assert a.names == b.names
    for name in a.names:
        np.testing.assert_array_equal(a.columns[name], b.columns[name])  # NaN where missing, in both
        np.testing.assert_array_equal(a.valid[name], b.valid[name])
    np.testing.assert_array_equal(a.rows, b.rows)


@pytest.fixture
def twin(tmp_path):
    return load(write(tmp_path / "comma.csv", COMMA))


# --------------------------------------------------------------------------- dialects read alike


@pytest.mark.parametrize("name, text, bom, crlf, kw", [
    ("semicolon_decimal_comma", dialect(COMMA, ";", ","), False, False, {"decimal": ","}),
    ("semicolon_decimal_comma_given", dialect(COMMA, ";", ","), False, False, {"decimal": ",", "delimiter": ";"}),
    ("semicolon_point", dialect(COMMA, ";"), False, False, {}),
    ("tab", dialect(COMMA, "\t"), False, False, {}),
    ("tab_decimal_comma", dialect(COMMA, "\t", ","), False, False, {"decimal": ","}),
    ("bom", COMMA, True, False, {}),
    ("crlf", COMMA, False, True, {}),
    ("bom_crlf_semicolon_decimal_comma", dialect(COMMA, ";", ","), True, True, {"decimal": ","}),
])
def test_every_dialect_loads_the_numbers_of_its_comma_twin(tmp_path, twin, name, text, bom, crlf, kw):
    data = load(write(tmp_path / f"{name}.csv", text, bom, crlf), **kw)
    assert_same(data, twin)
    assert data.columns["pm"][3] == -1.5e-3 and not data.valid["pm"][2] and not data.valid["f"][3]
    assert data.notes == ()


def test_semicolon_with_decimal_commas_is_not_taken_for_commas(tmp_path):
    # Every row splits evenly on commas too ("0;600" | "5"); only ';' gives numbers.
    text = "Zeit [s];P, MW\n0;600,5\n1;601,5\n2;602,5\n"
    data = load(write(tmp_path / "de.csv", text), time_column="Zeit [s]", decimal=",")
    np.testing.assert_array_equal(data.columns["P, MW"], [600.5, 601.5, 602.5])
    # without decimal = ",", the delimiter is still ';' and the commas are named
    with pytest.raises(DataError, match=re.escape("'600,5' is not a number")) as e:
        load(write(tmp_path / "de.csv", text), time_column="Zeit [s]")
    assert e.value.row == 2 and 'set [data] decimal = ","' in str(e.value)


def test_a_large_decimal_comma_file_reads_as_its_twin(tmp_path):
    n = 50_000
    t, p = np.arange(n) * 0.02, 0.6 + 1e-3 * np.sin(np.arange(n) / 50)
    comma = "time,pm\n" + "".join(f"{a:.2f},{b:.9f}\n" for a, b in zip(t, p))
    a = load(write(tmp_path / "a.csv", comma))
    b = load(write(tmp_path / "b.csv", dialect(comma, ";", ",")), decimal=",")
    assert_same(a, b)
    assert len(b) == n and b.rows[-1] == n + 1


def test_pmu_export_with_semicolons_and_decimal_commas(tmp_path):
    comma = ("ts,FREQ,P\n2024-03-01T12:00:00.000Z,50.01,240.5\n2024-03-01T12:00:00.020Z,49.99,241.25\n"
             "2024-03-01T12:00:00.040Z,49.98,242.0\n")
    epoch = "ts;FREQ;P\n1709294400,000;50,01;240,5\n1709294400,020;49,99;241,25\n1709294400,040;49,98;242,0\n"
    a = load(write(tmp_path / "a.csv", comma), timestamp="ts")
    for k, text in enumerate((dialect(comma, ";", ","), epoch)):
        b = load(write(tmp_path / f"b{k}.csv", text, bom=True, crlf=True), timestamp="ts", decimal=",")
        assert_same(a, b)
    np.testing.assert_array_equal(a.time, [0.0, 0.02, 0.04])


# --------------------------------------------------------------------------- a units row


def test_a_units_row_is_skipped_and_said(tmp_path):
    text = "time;pm;f\ns;pu;Hz\n" + "".join(dialect(COMMA, ";", ",").splitlines(keepends=True)[1:])
    path = write(tmp_path / "units.csv", text)
    with pytest.warns(SkippedRowWarning, match=r"row 2 holds units \(time s, pm pu, f Hz\), not a sample: skipped"):
        data = load(path, decimal=",")
    assert data.notes == ("row 2 holds units (time s, pm pu, f Hz), not a sample: skipped",)
    assert data.rows[0] == 3 and data.columns["pm"][0] == 0.6
    assert data.window(0.0, 0.05).notes == data.notes  # the note stays with the recording


def test_a_units_row_is_kept_with_the_recording(tmp_path):
    with pytest.warns(SkippedRowWarning):
        data = load(write(tmp_path / "u.csv", "time,pm,f\ns,,mHz\n0,1,50\n1,2,50\n"))
    assert dict(data.units) == {"f": "mHz"}  # a blank cell states nothing
    assert dict(data.window(0.0, 1.0).units) == {"f": "mHz"}


def test_a_units_row_that_contradicts_the_config_is_refused_naming_both(tmp_path):
    """Issue 56: a column in mHz read as Hz lay a thousand times off and was refused as
    'every value is blank or masked'. A units row that states the config's unit, or a
    unit at its base where the config gives none, reads as before."""
    folder = tmp_path / "test1"
    shutil.copytree(REPO / "experiments" / "test1", folder)
    csv = folder / "test1.csv"
    lines = csv.read_text().splitlines(keepends=True)
    csv.write_text(lines[0] + "s,kW\n" + "".join(lines[1:]))
    with pytest.raises(ConfigError) as e:
        with pytest.warns(SkippedRowWarning):
            load_experiment(folder)
    assert e.value.key == "data.outputs.pm.unit"
    assert "gives column 'pm' in 'kW', but the config reads it in its own units" in str(e.value)
    csv.write_text(lines[0] + "s,pu\n" + "".join(lines[1:]))
    with pytest.warns(SkippedRowWarning):
        assert load_experiment(folder).data.units == {"pm": "pu"}


def test_a_units_row_may_leave_a_cell_blank_and_a_bad_row_later_is_still_refused(tmp_path):
    with pytest.warns(SkippedRowWarning, match=r"units \(time s, f Hz\)"):
        data = load(write(tmp_path / "u.csv", "time,pm,f\ns,,Hz\n0,1,50\n1,2,50\n"))
    assert len(data) == 2
    with pytest.raises(DataError, match=r"row 4: column 'time': 's' is not a number"):
        load(write(tmp_path / "u.csv", "time,pm\ns,MW\n0,1\ns,MW\n"))


def test_a_time_unit_in_the_units_row_must_be_the_one_read(tmp_path):
    path = write(tmp_path / "ms.csv", "time;pm\nms;MW\n0;1\n20;2\n")
    with pytest.raises(DataError) as e:
        load(path)
    assert e.value.file == str(path) and e.value.row == 2
    assert "'ms'" in str(e.value) and 'time_unit = "ms"' in str(e.value)
    with pytest.warns(SkippedRowWarning):
        np.testing.assert_array_equal(load(path, time_unit="ms").time, [0.0, 0.02])


# --------------------------------------------------------------------------- refusals


def test_an_ambiguous_file_is_refused_at_its_row(tmp_path):
    # Header and rows split into two fields on ';' and on ','; under neither are they numbers.
    path = write(tmp_path / "amb.csv", "Zeit;Status,Wert\n0;ok,1\n1;ok,2\n")
    with pytest.raises(DataError) as e:
        load(path)
    message = str(e.value)
    assert e.value.file == str(path) and e.value.row == 2
    assert message.startswith(f"{path}, row 2: cannot tell the delimiter")
    assert "on ',' (0;ok | 1) and on ';' (0 | ok,1)" in message
    assert message.endswith('say which: [data] delimiter = "," or ";"')
    data = load(write(tmp_path / "ok.csv", "Zeit;Status,Wert\n0;1\n1;2\n"), time_column="Zeit")
    assert data.names == ("Status,Wert",)


def test_a_bad_value_in_a_decimal_comma_file_names_row_column_and_value(tmp_path):
    lines = dialect(COMMA, ";", ",").splitlines(keepends=True)
    lines[4] = "0,06;1,5x;49,96\n"
    path = write(tmp_path / "bad.csv", "".join(lines), crlf=True)
    with pytest.raises(DataError) as e:
        load(path, decimal=",")
    assert e.value.file == str(path) and e.value.row == 5
    assert "column 'pm': '1,5x' is not a number" in str(e.value)


def test_a_point_in_a_decimal_comma_file_is_refused(tmp_path):
    path = write(tmp_path / "mixed.csv", "time;pm\n0,0;1.234\n0,02;1,5\n")
    with pytest.raises(DataError, match=r"row 2: column 'pm': '1\.234' has a '\.', but the decimal separator is ','"):
        load(path, decimal=",")


@pytest.mark.parametrize("text, kw, row, message", [
    ("time,pm\n0,1\n", {"delimiter": ";"}, 1, r"the header is one column, 'time,pm', split on ';'.*delimiter = \",\""),
    ("time,pm\n0.5,1\n", {"decimal": ","}, 1, r"splits on ',' only, but with a decimal comma"),
    ("time;pm\n0;1\n0,5;1;2\n", {}, 3, r"expected 2 fields \(time, pm\), found 3: '0,5;1;2'"),
])
def test_dialect_mistakes_name_the_file_and_row(tmp_path, text, kw, row, message):
    path = write(tmp_path / "x.csv", text)
    with pytest.raises(DataError, match=message) as e:
        load(path, **kw)
    assert e.value.file == str(path) and e.value.row == row


@pytest.mark.parametrize("kw, message", [
    ({"delimiter": "|x"}, r'delimiter "\|x" is not one of ",", ";", "\\t"'),
    ({"decimal": ";"}, r'decimal separator ";" is not one of ".", ","'),
    ({"delimiter": ",", "decimal": ","}, r'a decimal comma needs a delimiter other than ","'),
])
def test_a_dialect_that_cannot_be_meant_is_refused_before_reading(tmp_path, kw, message):
    with pytest.raises(DataError, match=message):
        load(write(tmp_path / "x.csv", COMMA), **kw)


def test_text_that_is_not_utf8_is_refused_at_its_row(tmp_path):
    path = tmp_path / "latin.csv"
    path.write_bytes("time;pm\n0;1\nZeit [µs];2\n".encode("cp1252"))
    with pytest.raises(DataError, match=r"row 3: not UTF-8 text: byte 0xb5") as e:
        load(path)
    assert e.value.file == str(path)


# --------------------------------------------------------------------------- the experiment config


def config(tmp_path: Path, data_file: str, extra: str = "") -> Path:
    """experiments/test1/config.toml with its data file replaced and [data] keys added."""
    text = (TEST1 / "config.toml").read_text()
    text = text.replace('file = "test1.csv"', f'file = "{data_file}"\n{extra}')
    folder = tmp_path / Path(data_file).stem
    folder.mkdir(exist_ok=True)
    (folder / "config.toml").write_text(text)
    return folder / "config.toml"


def test_an_experiment_on_a_semicolon_decimal_comma_export_is_its_comma_twin(tmp_path):
    comma = (TEST1 / "test1.csv").read_text()
    a = config(tmp_path, "comma.csv")
    write(a.parent / "comma.csv", comma)
    b = config(tmp_path, "de.csv", 'delimiter = ";"\ndecimal = ","')
    write(b.parent / "de.csv", dialect(comma, ";", ","), bom=True, crlf=True)
    c = config(tmp_path, "detected.csv", 'decimal = ","')
    write(c.parent / "detected.csv", dialect(comma, ";", ","))
    d = config(tmp_path, "tab.csv", 'delimiter = "\\t"')
    write(d.parent / "tab.csv", dialect(comma, "\t"))
    ea = load_experiment(a)
    for other in (b, c, d):
        eb = load_experiment(other)
        assert_same(eb.data, ea.data)
        assert eb.noise_sigma == ea.noise_sigma and eb.window == ea.window


def test_an_experiment_keeps_the_note_of_a_skipped_units_row(tmp_path):
    comma = (TEST1 / "test1.csv").read_text().splitlines(keepends=True)
    path = config(tmp_path, "units.csv", 'decimal = ","')
    write(path.parent / "units.csv", dialect(comma[0] + "s,pu\n" + "".join(comma[1:]), ";", ","))
    with pytest.warns(SkippedRowWarning, match="row 2 holds units"):
        exp = load_experiment(path)
    assert exp.data.notes == ("row 2 holds units (time s, pm pu), not a sample: skipped",)
    assert exp.data.rows[0] == 3
    said = "units.csv: row 2 holds units (time s, pm pu), not a sample: skipped"  # as the CLI and the report say it
    assert said in exp.recording.lines() and not exp.recording.plain


@pytest.mark.parametrize("extra, key, message", [
    ('delimiter = "|x"', "data.delimiter", r'delimiter "\|x" is not one of ",", ";", "\\t"; leave it out to detect'),
    ('delimiter = ""', "data.delimiter", r'delimiter "" is not one of'),
    ("delimiter = 59", "data.delimiter", r"expected a non-empty string, got 59"),
    ('decimal = ";"', "data.decimal", r'decimal ";" is not one of ".", ","'),
    ('delimiter = ","\ndecimal = ","', "data.decimal",
     r'decimal = "," needs a delimiter other than ","'),
    ('delimeter = ";"', "data.delimeter", r"unknown key 'delimeter' \(did you mean 'delimiter'\?\)"),
])
def test_wrong_dialect_keys_are_refused_by_key(tmp_path, extra, key, message):
    path = config(tmp_path, "x.csv", extra)
    write(path.parent / "x.csv", (TEST1 / "test1.csv").read_text())
    with pytest.raises(ConfigError, match=message) as e:
        load_experiment(path)
    assert e.value.key == key and e.value.file == str(path)


def test_a_config_with_the_wrong_decimal_is_refused_at_the_data_row(tmp_path):
    path = config(tmp_path, "de.csv")  # decimal left at "."
    write(path.parent / "de.csv", dialect((TEST1 / "test1.csv").read_text(), ";", ","))
    with pytest.raises(DataError, match=r"de\.csv, row 2: column 'time': '0,0000' is not a number.*decimal = \",\""):
        load_experiment(path)


def test_estimate_says_a_units_row_once(tmp_path, capsys):
    """Issue 56: the note came as a warning and again among the recording's lines."""
    from rapid_cosim.cli import main

    folder = tmp_path / "test1"
    shutil.copytree(REPO / "experiments" / "test1", folder)
    csv = folder / "test1.csv"
    lines = csv.read_text().splitlines(keepends=True)
    csv.write_text(lines[0] + "s,pu\n" + "".join(lines[1:]))
    assert main(["estimate", str(folder), "--method", "nm:2", "--archive", str(tmp_path / "run.h5"), "--quiet"]) == 0
    out = capsys.readouterr()
    assert (out.out + out.err).count("holds units (time s, pm pu)") == 1, out
