"""docs/config.md is the schema's page, every parser accepts exactly the keys it lists, and
an error's key links to its entry there."""

from __future__ import annotations

import re
import shutil
import tomllib
from pathlib import Path

import pytest

from rapid_cosim.errors import ConfigError, RapidCosimError
from rapid_cosim.experiment import definition, electrical, load_experiment, recording, render_config, schema, signals
from rapid_cosim.experiment.schema import CONFIG, FLEET_FILE, PAGE, TOLERANCE_FILE, UNIT_FILE, lit, reference

REPO = Path(__file__).resolve().parents[1]
UNKNOWN = "zz_unknown"
SAMPLE = {"<output>": "pm", "<input>": "f_dev", "<parameter>": "gov.R"}  # test1's names for the user's names
MINIMAL = {"data.outputs.<output>": {"column": "pm"}, "data.flags": {"column": "pm"},
           "inputs.<input>": {"column": "pm"}, "inputs.<input>.gaps": {"max": 1.0}, "noise.<output>": {"dt": 0.1},
           "noise.<output>.components": {"sigma": 0.001, "tau": 1.0}}


def _anchors(text: str) -> list[str]:
    """As tests/test_docs.py resolves them: headings' slugs and ``<a id>``s."""
    headings = [re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-")
                for h in re.findall(r"^#+ (.+)$", text, flags=re.MULTILINE)]
    return headings + re.findall(r'<a id="([^"]+)"></a>', text)


def _unknown(e: RapidCosimError, key: str) -> bool:
    return isinstance(e, ConfigError) and e.detail.startswith("unknown") and key in e.detail


# ------------------------------------------------------------------ the page


def test_the_page_is_what_the_schema_writes():
    assert (REPO / PAGE).read_text(encoding="utf-8") == schema.reference_markdown(), \
        "docs/config.md is stale: rapid-cosim docs config > docs/config.md"


def test_every_key_has_one_anchor():
    anchors = _anchors((REPO / PAGE).read_text(encoding="utf-8"))
    assert len(anchors) == len(set(anchors)), sorted(a for a in anchors if anchors.count(a) > 1)
    for kind in schema.KINDS:
        for s in kind.sections:
            assert {s.anchor(k) for k in (*s.keys, *((s.open,) if s.open else ()))} <= set(anchors), s.name


def test_the_values_the_page_states_are_the_parsers():
    """Allowed values and defaults written in the schema (their modules read their keys
    from it, so it cannot import them) are the parsers' own."""
    from rapid_cosim.identify.unit import MVA_RANGE
    from rapid_cosim.structures.shipped import KINDS
    from rapid_cosim.validation.tolerances import DEFAULT_BANDS, TERM_RANGES

    assert schema.UNITS == tuple(signals.UNITS) and schema.CONVERSIONS == signals.CONVERSIONS
    assert schema.BASELINES == signals.BASELINES and schema.SCALES == definition.SCALES
    assert schema.FLAG_KINDS == recording.FLAG_KINDS and schema.FILLS == recording.FILLS
    assert {k.name: k.default for k in schema.DATA_LIMITS.keys} == {k: lit(v) for k, v in recording.LIMITS.items()}
    assert CONFIG.section("simulation").keys[3].default == lit(definition.DEFAULT_TIMEOUT)
    assert f'"{definition.NOISE_PRE_STEP}"' in CONFIG.section("fitness").keys[3].allowed
    assert "0.25" in schema.GAPS.keys[0].allowed and recording.SHORT_GAP == 0.25
    assert "mach.H` {:g} to {:g} s".format(*electrical.H_RANGE) in schema.FIXED.open.allowed
    assert "mach.D` {:g} to {:g} pu".format(*electrical.D_RANGE) in schema.FIXED.open.allowed
    unit_keys = {k.name: k for k in UNIT_FILE.section("unit").keys}
    assert unit_keys["mva"].allowed == "{:g} to {:g}".format(*MVA_RANGE)
    assert unit_keys["kind"].allowed == tuple(KINDS)
    for key in TOLERANCE_FILE.section("validation").keys:
        assert tomllib.loads(f"x = {key.default.strip('`')}")["x"] == DEFAULT_BANDS[key.name]
    for key in TOLERANCE_FILE.section("validation.<metric>").keys:
        assert key.allowed == "> {:g} and <= {:g}".format(*TERM_RANGES[key.name])


# ------------------------------------------------------------------ the experiment config


@pytest.fixture
def folder(tmp_path) -> Path:
    shutil.copy(REPO / "experiments" / "test1" / "test1.csv", tmp_path)
    return tmp_path


def _load(folder: Path, raw: dict):
    (folder / "config.toml").write_text(render_config(raw))
    return load_experiment(folder / "config.toml")


def _base() -> dict:
    return tomllib.loads((REPO / "experiments" / "test1" / "config.toml").read_text())


def _table(raw: dict, name: str) -> dict:
    """The table of ``raw`` that section ``name`` is, made (minimal and valid) where missing."""
    table, parts = raw, name.split(".")
    for depth, part in enumerate(parts):
        here, part = ".".join(parts[:depth + 1]), SAMPLE.get(part, part)
        if part == "components":
            table[part] = [dict(MINIMAL[here])]
            table = table[part][0]
            continue
        if not isinstance(table.get(part), dict):
            table[part] = dict(MINIMAL.get(here, {}))
        table = table[part]
    return table


def test_test1_loads_as_the_base(folder):
    assert _load(folder, _base()).name == "test1"


CHECKED = [s.name for s in CONFIG.sections if s.strict and s.open is None]


@pytest.mark.parametrize("name", CHECKED)
def test_the_config_refuses_a_key_the_page_does_not_list(folder, name):
    raw = _base()
    _table(raw, name)[UNKNOWN] = 1
    with pytest.raises(ConfigError) as e:
        _load(folder, raw)
    assert _unknown(e.value, UNKNOWN) and e.value.key.endswith(UNKNOWN), e.value


def test_the_config_refuses_a_section_the_page_does_not_list(folder):
    with pytest.raises(ConfigError, match=f"unknown top-level key '{UNKNOWN}'"):
        _load(folder, {**_base(), UNKNOWN: {}})
    assert set(CONFIG.accepted()) == {s.name for s in CONFIG.sections if "." not in s.name}


@pytest.mark.parametrize("name", CHECKED + ["fixed"])
def test_the_config_accepts_every_key_the_page_lists(folder, name):
    """Each key, with a value that may be wrong: whatever the error, not an unknown key."""
    for key in CONFIG.section(name).keys:
        raw = _base()
        _table(raw, name).setdefault(key.name, "zz")
        try:
            _load(folder, raw)
        except RapidCosimError as e:
            assert not _unknown(e, key.name), e


# ------------------------------------------------------------------ the other files


def _unit_folder(tmp_path: Path) -> Path:
    (tmp_path / "t1").mkdir(parents=True)
    (tmp_path / "t1" / "config.toml").write_text("")
    (tmp_path / "s.toml").write_text("")
    return tmp_path


UNIT_RAW = {"unit": {"name": "u"}, "tests": {"configs": ["t1"]}, "structures": {"files": ["s.toml"]}}


@pytest.mark.parametrize("section", list(UNIT_FILE.accepted()))
def test_the_unit_file_takes_exactly_the_listed_keys(tmp_path, section):
    from rapid_cosim.identify.unit import Unit

    folder = _unit_folder(tmp_path)
    for key in UNIT_FILE.accepted()[section]:
        raw = {s: dict(t) for s, t in UNIT_RAW.items()}
        raw[section].setdefault(key, "zz")
        (folder / "unit.toml").write_text(render_config(raw))
        try:
            Unit.load(folder)
        except RapidCosimError as e:
            assert not _unknown(e, key), e
    raw = {s: dict(t) for s, t in UNIT_RAW.items()}
    raw[section][UNKNOWN] = 1
    (folder / "unit.toml").write_text(render_config(raw))
    with pytest.raises(ConfigError, match=f"unknown key.*{UNKNOWN}"):
        Unit.load(folder)
    (folder / "unit.toml").write_text(render_config({**UNIT_RAW, UNKNOWN: {"a": 1}}))
    with pytest.raises(ConfigError, match=f"unknown section.*{UNKNOWN}"):
        Unit.load(folder)


def test_the_fleet_file_takes_exactly_the_listed_keys(tmp_path):
    from rapid_cosim.fleet.spec import load_fleet

    (tmp_path / "u").mkdir()
    (tmp_path / "u" / "unit.toml").write_text("")
    (tmp_path / "bands.toml").write_text("")
    for key in FLEET_FILE.accepted()["fleet"]:
        value = {"units": ["u"], "tolerances": "bands.toml", "records": "bands.toml", "name": "f"}[key]
        (tmp_path / "fleet.toml").write_text(render_config({"fleet": {"units": ["u"], key: value}}))
        assert load_fleet(tmp_path).units
    for raw, message in (({"fleet": {"units": ["u"], UNKNOWN: 1}}, "unknown key"),
                         ({"fleet": {"units": ["u"]}, UNKNOWN: {"a": 1}}, "one section")):
        (tmp_path / "fleet.toml").write_text(render_config(raw))
        with pytest.raises(ConfigError, match=f"{message}.*{UNKNOWN}"):
            load_fleet(tmp_path)


def test_the_tolerance_file_takes_exactly_the_listed_metrics_and_terms(tmp_path):
    from rapid_cosim.validation.tolerances import load_tolerances

    path = tmp_path / "bands.toml"
    terms = {k.name for k in TOLERANCE_FILE.section("validation.<metric>").keys}
    for metric, allowed in schema.METRIC_TERMS.items():
        for term in sorted(terms):
            path.write_text(render_config({"validation": {metric: {term: 0.5}}}))
            if term in allowed:
                assert load_tolerances(path).bands[metric] == {term: 0.5}
            else:
                with pytest.raises(ConfigError, match=f"unknown term '{term}'"):
                    load_tolerances(path)
    path.write_text(render_config({"validation": {UNKNOWN: {}}}))
    with pytest.raises(ConfigError, match=f"unknown metric '{UNKNOWN}'"):
        load_tolerances(path)


def test_a_structure_file_refuses_what_the_page_does_not_list_naming_itself(folder):
    """The structure loader reads the listed sections and keys and refuses others; its
    [fixed], [estimate] and [optional] entries are checked as a config's are when the
    file is read, each error naming the structure file (not a test's config)."""
    from rapid_cosim.structures.structure import Structure

    structure = schema.STRUCTURE_FILE.section("structure")
    assert structure.strict and schema.STRUCTURE_FILE.strict
    source = REPO / "experiments" / "structures" / "IEEEG1.toml"
    s = Structure.load(source)
    raw = tomllib.loads(source.read_text())
    assert (s.name, s.bench, s.input_bench) == tuple(raw["structure"][k.name] for k in structure.keys)
    assert s.carries == {"gov.Uo": "rate_limit", "gov.Uc": "rate_limit", "gov.db": "deadband"}
    assert s.effects == ("rate_limit", "deadband") and [v.name for v in s.optional_variants()] == [
        "IEEEG1+rate_limit", "IEEEG1+rate_limit(Uo)", "IEEEG1+rate_limit(Uc)", "IEEEG1+deadband"]
    for where, edit in (("structure", lambda r: r["structure"].__setitem__(UNKNOWN, 1)),
                        (UNKNOWN, lambda r: r.__setitem__(UNKNOWN, {"a": 1})),
                        ("estimate", lambda r: r["estimate"][next(iter(r["estimate"]))].__setitem__(UNKNOWN, 1)),
                        ("optional", lambda r: r["optional"][next(iter(r["optional"]))].__setitem__(UNKNOWN, 1))):
        raw = tomllib.loads(source.read_text())
        edit(raw)
        (folder / "s.toml").write_text(render_config(raw))
        with pytest.raises(ConfigError) as e:
            Structure.load(folder / "s.toml")
        assert e.value.file == str(folder / "s.toml") and UNKNOWN in str(e.value), (where, e.value)
        assert e.value.key.startswith(where), (where, e.value.key)


# ------------------------------------------------------------------ links from errors


def _error(call) -> ConfigError:
    with pytest.raises(ConfigError) as e:
        call()
    return e.value


def test_an_errors_key_links_to_its_entry(folder, tmp_path):
    from rapid_cosim.identify.unit import Unit
    from rapid_cosim.validation.tolerances import load_tolerances

    def broken(name: str, key: str, value):
        raw = _base()
        _table(raw, name)[key] = value
        return _error(lambda: _load(folder, raw)).key

    keys = [broken("data", "delimiter", "|"), broken("estimate.<parameter>", "min", "x"),
            broken("simulation", "timeout", -1.0), broken("inputs.<input>.gaps", "max", 100.0),
            broken("data.outputs.<output>", "unit", "parsec"), broken("fixed", "gov.p_ref", "x"),
            broken("noise.<output>.components", "tau", -1.0), broken("data", UNKNOWN, 1),
            broken("estimate", "gov.Ts", 3.0)]
    unit = _unit_folder(tmp_path / "unit")
    for raw in ({**UNIT_RAW, "unit": {"mva": -3}}, {**UNIT_RAW, "structures": {"files": ["nowhere.toml"]}}):
        (unit / "unit.toml").write_text(render_config(raw))
        keys.append(_error(lambda: Unit.load(unit)).key)
    (tmp_path / "bands.toml").write_text("[validation]\nrmse = { noise = 1000.0 }\n")
    keys.append(_error(lambda: load_tolerances(tmp_path / "bands.toml")).key)
    assert keys == ["data.delimiter", 'estimate."gov.R".min', "simulation.timeout", "inputs.f_dev.gaps.max",
                    "data.outputs.pm.unit", 'fixed."gov.p_ref"', "noise.pm.components[0]", f"data.{UNKNOWN}",
                    'estimate."gov.Ts"', "unit.mva", "structures.files", "validation.rmse.noise"]
    anchors = set(_anchors((REPO / PAGE).read_text(encoding="utf-8")))
    links = [reference(k) for k in keys]
    assert all(link and link.startswith(f"{PAGE}#") and link.split("#")[1] in anchors for link in links), links
    assert links[:4] == [f"{PAGE}#data.delimiter", f"{PAGE}#estimate.parameter.min", f"{PAGE}#simulation.timeout",
                         f"{PAGE}#inputs.input.gaps.max"]
    assert links[6:9] == [f"{PAGE}#noise.output.components", f"{PAGE}#data", f"{PAGE}#estimate.parameter"]
    assert reference("fleet.units") == f"{PAGE}#fleet.units" and reference("optional") == f"{PAGE}#optional"
    assert reference(UNKNOWN) is None
