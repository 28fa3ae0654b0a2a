"""iGrGen as the field writes Modelica: every class documented with its source and
revisions, units written once (iGrGen.Types), and the FMUs still carrying each
declaration's unit, range, description and causality through the derived types."""

from __future__ import annotations

import re

from fmpy import read_model_description


def _classes(repo):
    return sorted(p for p in (repo / "modelica" / "iGrGen").rglob("*.mo"))


def test_every_class_has_documentation_with_revisions(repo):
    missing = [str(p.relative_to(repo)) for p in _classes(repo)
               if not re.search(r"Documentation\(\s*info\s*=", p.read_text()) or "revisions=" not in p.read_text()]
    assert not missing, f"without Documentation(info=..., revisions=...): {missing}"


def test_units_are_written_once_in_types(repo):
    scattered = [f"{p.relative_to(repo)}:{k}" for p in _classes(repo) if p.parent.name != "Types"
                 for k, line in enumerate(p.read_text().splitlines(), 1) if "unit=" in line]
    assert not scattered, f"unit= outside iGrGen.Types: {scattered}"


def test_derived_parameters_are_final(repo):
    text = (repo / "modelica" / "iGrGen" / "Effects" / "Deadband.mo").read_text()
    assert re.search(r"final parameter Types.PerUnit d = db / f_nom", text)


def test_fmus_keep_units_ranges_descriptions_and_causality(fmus):
    md = read_model_description(str(fmus["FrequencyInput"]))
    by_name = {v.name: v for v in md.modelVariables}
    ts = by_name["gov.Ts"]
    assert (ts.unit, ts.min, ts.max, ts.description) == ("s", "0.001", "100.0", "governor time constant")
    assert by_name["f_dev"].causality == "input" and by_name["f_dev"].unit == "Hz"
    assert by_name["pm"].causality == "output" and by_name["pm"].description == "mechanical power (pu)"
    md = read_model_description(str(fmus["StagedTestRateLimit"]))
    rate = {v.name: v for v in md.modelVariables}["gov.rate_open"]
    assert rate.causality == "parameter" and rate.unit == "1/s"
