"""Bad Modelica gets an error that names the file, the line and the construct."""

import shutil
from pathlib import Path

import pytest

from rapid_cosim.compiler import build_models
from rapid_cosim.compiler.embedded.frontend import parse, translate
from rapid_cosim.compiler.modelica_source import load_package
from rapid_cosim.errors import ModelicaError, ModelicaSyntaxError, UnsupportedConstruct


@pytest.fixture
def package(tmp_path, repo) -> Path:
    """A private copy of iGrGen to break."""
    dst = tmp_path / "iGrGen"
    shutil.copytree(repo / "modelica" / "iGrGen", dst)
    return dst


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


def _line_of(path: Path, needle: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if needle in line)


def _translate(package: Path, model: str = "iGrGen.TestBenches.StagedTest"):
    source = load_package(package)
    return translate(source, model, parse(source))


def test_line_map_points_into_the_right_file(package):
    source = load_package(package)
    line = next(i for i, text in enumerate(source.text.splitlines(), 1) if "der(xg1) = (pin - xg1) / Ts;" in text)
    file, file_line = source.locate(line)
    assert Path(file).name == "TGTypeI.mo"
    assert file_line == _line_of(package / "Governors" / "TGTypeI.mo", "der(xg1) = (pin - xg1) / Ts;")


def test_syntax_error_names_file_and_line(package):
    f = package / "Governors" / "TGTypeI.mo"
    _edit(f, "der(xg1) = (pin - xg1) / Ts;", "der(xg1) = (pin - xg1) / Ts")  # no semicolon: the parser trips on the next line
    with pytest.raises(ModelicaSyntaxError) as info:
        _translate(package)
    assert info.value.file == str(f)
    assert info.value.line == _line_of(f, "xv = xg1;")
    assert "TGTypeI.mo:" in str(info.value)


@pytest.mark.parametrize("construct, old, new, needle", [
    ("when-equation", "xv = xg1;", "xv = xg1;\n  when time > 5 then\n  end when;", "when time > 5"),
    ("delay()", "xv = xg1;", "xv = delay(xg1, 0.1);", "delay(xg1"),
    ("pre()", "xv = xg1;", "xv = pre(xg1);", "pre(xg1)"),
    ("initial()", "xv = xg1;", "xv = if initial() then xg1 else xg1;", "initial()"),
    ("redeclare", "extends PartialTGTypeI;", "extends PartialTGTypeI(redeclare Real xv);", "redeclare"),
    ("if-equation", "xv = xg1;", "if Ts > 1 then\n    xv = xg1;\n  else\n    xv = xg1;\n  end if;", "if Ts > 1"),
])
def test_unsupported_construct_names_file_line_and_construct(package, construct, old, new, needle):
    f = package / "Governors" / "TGTypeI.mo"
    _edit(f, old, new)
    with pytest.raises(UnsupportedConstruct) as info:
        _translate(package)
    assert construct in str(info.value)
    assert info.value.file == str(f)
    assert info.value.line == _line_of(f, needle)


def test_unsupported_construct_in_an_unused_class_does_not_matter(package):
    _edit(package / "Effects" / "PadeDelay.mo", "der(x1) = x2;", "der(x1) = delay(x2, 0.1);")
    _translate(package, "iGrGen.TestBenches.StagedTestDelay")  # its delay is exact: no PadeDelay in it
    (package / "TestBenches" / "StagedTestPade.mo").write_text(
        "within iGrGen.TestBenches;\nmodel StagedTestPade\n  Sources.FrequencyStep src;\n  Effects.PadeDelay dly;\n"
        "  Governors.TGTypeI gov;\n  output Real pm;\nequation\n  connect(src.y, dly.u);\n  connect(dly.y, gov.dw);\n"
        "  pm = gov.pm.signal;\nend StagedTestPade;\n")
    order = package / "TestBenches" / "package.order"
    order.write_text(order.read_text() + "StagedTestPade\n")
    with pytest.raises(UnsupportedConstruct, match=r"delay\(\)"):
        _translate(package, "iGrGen.TestBenches.StagedTestPade")


def test_unknown_function_is_located(package):
    f = package / "Governors" / "TGTypeI.mo"
    _edit(f, "xv = xg1;", "xv = myClamp(xg1);")
    with pytest.raises(UnsupportedConstruct, match="myClamp") as info:
        _translate(package)
    assert (info.value.file, info.value.line) == (str(f), _line_of(f, "myClamp"))


def test_nonlinear_algebraic_loop_is_rejected(package):
    _edit(package / "Governors" / "TGTypeI.mo", "xv = xg1;", "xv = xg1 - 0.1 * xv ^ 3;")
    with pytest.raises(UnsupportedConstruct, match="nonlinear algebraic loop.*gov.xv"):
        _translate(package)


def test_undetermined_variable_is_named(package):
    _edit(package / "Governors" / "TGTypeI.mo", "xv = xg1;", "")
    with pytest.raises(ModelicaError, match="not determined by any equation: .*gov.xv"):
        _translate(package)


def test_unknown_model_lists_the_test_benches(package, tmp_path):
    with pytest.raises(Exception, match="StagedTest"):
        build_models(["iGrGen.TestBenches.NoSuchBench"], package=package, fmu_dir=tmp_path / "f", log=lambda *_: None)
