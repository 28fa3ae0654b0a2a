"""PSS/E .dyr and PSLF .dyd records (rapid_cosim.exchange): the tables against the Modelica
source, round trips, the errors a bad record gets, and andes (a parser nobody here wrote)
reading every exported .dyr record to the same values."""

from __future__ import annotations

import re
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest

from rapid_cosim.errors import ParameterError, RecordError
from rapid_cosim.exchange import MODELS, ExchangeWarning, model_named, pslf_dyd, psse_dyr, read_record
from rapid_cosim.exchange.tables import record_numbers

ROOT = Path(__file__).resolve().parents[1]
GOVERNORS = ROOT / "modelica" / "iGrGen" / "Governors"
STRUCTURES = ROOT / "experiments" / "structures"
_PARAM = re.compile(r"^\s*parameter\s+[\w.]+\s+(\w+)\s*(?:\(([^)]*)\))?\s*=\s*([^\s\";]+)", re.M)


def modelica_parameters(model: str) -> dict[str, tuple[float, float, str]]:
    """name -> (min, max, default text) of the block's non-final parameters."""
    out = {}
    for name, attrs, default in _PARAM.findall((GOVERNORS / f"{model}.mo").read_text()):
        bounds = dict(re.findall(r"(min|max)\s*=\s*([-\d.e]+)", attrs or ""))
        out[name] = (float(bounds.get("min", "-inf")), float(bounds.get("max", "inf")), default)
    return out


def calibrated_values(model: str) -> dict[str, float]:
    """What an export of the standard structure writes: its fixed values and each
    estimate at the middle of its range (IEEEG1's K3 the rest of the shaft: K3_rest)."""
    raw = tomllib.loads((STRUCTURES / f"{model}.toml").read_text())
    values = {k.removeprefix("gov."): float(v) for k, v in raw["fixed"].items()}
    for name, spec in raw["estimate"].items():
        lo, hi = spec["min"], spec["max"]
        values[name.removeprefix("gov.")] = float(np.sqrt(lo * hi) if spec.get("scale") == "log" else (lo + hi) / 2)
    if model == "IEEEG1":
        values.update(Uo=0.0101, Uc=-0.0298)  # the field unit's asymmetric rates
    return values


def test_an_ieeeg1_record_carries_stages_that_sum_to_one(tmp_path):
    """The structure file's K3_rest: the .dyr's K3 is 1 - K1 (K5 = K7 = 0), so the record
    read back (K3 explicit) is the model calibrated."""
    values = calibrated_values("IEEEG1")
    assert values["K3_rest"] == 1.0 and values["K5"] == values["K7"] == 0.0
    psse_dyr.write_record(tmp_path / "unit.dyr", "IEEEG1", values, bus=7, machine_id="2")
    record = read_record(tmp_path / "unit.dyr")
    assert record.values["K1"] + record.values["K3"] == pytest.approx(1.0, abs=1e-15)
    assert record.values["K1"] == values["K1"]
    assert record.values["K3_rest"] == 0.0  # a record states its K3: read back, it is used as written


def _fields(model: str, values: dict) -> dict:
    """The values a record's fields carry (a record read back also says how it is read:
    IEEEG1's K3_rest 0)."""
    carried = {f.param for f in MODELS[model].fields if f.param}
    return {k: v for k, v in values.items() if k in carried}


@pytest.mark.parametrize("model", list(MODELS))
def test_every_parameter_is_carried_or_dropped_with_the_modelica_default_and_range(model):
    declared = modelica_parameters(model)
    table = MODELS[model]
    assert set(table.params) == set(declared)
    for f in table.fields:
        if f.param is None:
            continue
        lo, hi, default = declared[f.param]
        assert (f.lo, f.hi) == (lo, hi), f.param
        assert f.default == float(default), f.param
    for d in table.dropped:
        if d.default is not None:
            assert d.default == float(declared[d.param][2]), d.param


@pytest.mark.parametrize("model", list(MODELS))
def test_dyr_round_trip_is_identical(model, tmp_path):
    values = calibrated_values(model)
    first = psse_dyr.write_record(tmp_path / "unit.dyr", model, values, bus=7, machine_id="2")
    record = read_record(tmp_path / "unit.dyr")
    assert (record.model, record.bus, record.machine_id, record.mva) == (model, 7, "2", None)
    carried = _fields(model, values)
    assert carried == {k: record.values[k] for k in carried}
    again = psse_dyr.write_record(tmp_path / "again.dyr", model, record.values, bus=record.bus,
                                  machine_id=record.machine_id, extra=record.extra)
    assert again.text == first.text == (tmp_path / "again.dyr").read_text()


@pytest.mark.parametrize("model", list(MODELS))
def test_dyd_round_trip_is_identical(model, tmp_path):
    values = calibrated_values(model)
    first = pslf_dyd.write_record(tmp_path / "unit.dyd", model, values, bus=7, machine_id="2", mva=110.5,
                                  bus_name="GT 1", kv=13.8)
    record = read_record(tmp_path / "unit.dyd")
    assert (record.model, record.bus, record.machine_id, record.mva, record.bus_name, record.kv) == \
        (model, 7, "2", 110.5, "GT 1", 13.8)
    carried = _fields(model, values)
    assert carried == {k: record.values[k] for k in carried}
    again = pslf_dyd.write_record(tmp_path / "again.dyd", model, record.values, bus=7, machine_id="2",
                                  mva=record.mva, bus_name=record.bus_name, kv=record.kv, extra=record.extra)
    assert again.text == first.text


def test_dyr_and_dyd_of_one_model_read_to_the_same_values(tmp_path):
    values = calibrated_values("GGOV1")
    psse_dyr.write_record(tmp_path / "u.dyr", "GGOV1", values, bus=1)
    pslf_dyd.write_record(tmp_path / "u.dyd", "GGOV1", values, bus=1, mva=100.0)
    assert read_record(tmp_path / "u.dyr").values == read_record(tmp_path / "u.dyd").values


def test_free_format_records_among_other_models():
    text = ("  1 'GENROU' 1  8.0 0.03 0.4 0.05 6.5 0.0 1.8 1.7 0.3 0.55 0.25 0.06 0.0 0.0 /\n"
            "  1 'IEEEG1'  '1 ' 0 0 2.5D1 0.0 0.0 0.2 0.05 -0.08 1.0 0.0\n"
            "      0.3 0.25 0.0 7.0 0.75 0.0 0.6 0.0 0.0 0.05 0.0 0.0 / unit 1, from the OEM\n")
    records, others = psse_dyr.parse_records(text)
    assert list(map(str, others)) == ["GENROU (line 1)"] and (others[0].bus, others[0].machine_id) == (1, "1")
    (r,) = records
    assert (r.model, r.bus, r.machine_id, r.line) == ("IEEEG1", 1, "1", 2)
    assert r.values["K"] == 25.0 and r.values["T1"] == 0.001 and r.values["K1"] == 0.25
    assert (r.values["Uo"], r.values["Uc"], r.values["K3"]) == (0.05, -0.08, 0.75)


def test_dyd_positional_and_equals_forms():
    positional = 'tgov1 3 "GEN 3" 20.0 "1" : #9 mva=250.0 0.05 0.4 1.05 0.3 2.0 6.0 0.1\n'
    keyed = ('# a comment\nmodels\ntgov1 3 "GEN 3" 20.0 "1" : #9 mva=250.0 r=0.05 t1=0.4 /\n'
             '   vmax=1.05 vmin=0.3 t2=2.0 t3=6.0 dt=0.1\n')
    (a,), _ = pslf_dyd.parse_records(positional)
    (b,), _ = pslf_dyd.parse_records(keyed)
    assert a.values == b.values == {"R": 0.05, "T1": 0.4, "VMAX": 1.05, "VMIN": 0.3, "T2": 2.0, "T3": 6.0, "Dt": 0.1}
    assert (b.line, b.mva) == (3, 250.0)


def _error(parse, text: str) -> RecordError:
    with pytest.raises(RecordError) as info:
        parse(text, "unit.txt")
    return info.value


def test_bad_records_are_named_by_file_line_field_value_and_allowed_range(tmp_path):
    e = _error(psse_dyr.parse_records, "\n1 'TGOV1' 1 0.05 0.5 1.0 0.0 2.5 7.5 /\n")
    assert (e.file, e.line) == ("unit.txt", 2) and "takes 7 values, the record has 6" in str(e)
    assert "R T1 VMAX VMIN T2 T3 Dt" in str(e)
    e = _error(psse_dyr.parse_records, "1 'TGOV1' 1 0.05 0.5 one 0.0 2.5 7.5 0.0 /\n")
    assert (e.field, e.value, e.allowed) == ("VMAX", "one", "0 to 2") and "not a number" in str(e)
    assert str(e).startswith("unit.txt:1: field VMAX = 'one'")
    e = _error(psse_dyr.parse_records, "1 'TGOV1' 1 5.0 0.5 1.0 0.0 2.5 7.5 0.0 /\n")
    assert (e.field, e.allowed) == ("R", "0.001 to 1")
    e = _error(psse_dyr.parse_records, "1 'HYGOV' 1 0.05 0.3 5.0 0.05 0.5 0.2 1.0 0.0 1.0 1.2 0.5 0.08\n")
    assert "not ended by '/'" in str(e)
    ieeeg1 = "1 'IEEEG1' 1 0 0 20 0 0 0.1 1 -1 1 0 0.3 0.3 {k2} 7 0.7 0 0.6 0 0 0.05 0 0 /"
    e = _error(psse_dyr.parse_records, ieeeg1.format(k2=0.2))
    assert (e.field, e.allowed) == ("K2", "0 (no iGrGen counterpart)")
    ggov1 = psse_dyr.format_record("GGOV1", {}, bus=1)[0].replace("1 'GGOV1' 1 1 1", "1 'GGOV1' 1 -2 1")
    e = _error(psse_dyr.parse_records, ggov1)
    assert (e.field, e.value, e.allowed) == ("Rselect", "-2", "-1 or 0 or 1")
    turbine_base = psse_dyr.format_record("GGOV1", {}, bus=1, extra={"Trate": 45.0})[0]
    assert _error(psse_dyr.parse_records, turbine_base).field == "Trate"
    (ok,), _ = psse_dyr.parse_records(turbine_base, mva=45.0)
    assert ok.extra["Trate"] == 45.0
    (tmp_path / "turbine.dyr").write_text(turbine_base)
    assert read_record(tmp_path / "turbine.dyr", mva=45.0).extra["Trate"] == 45.0

    (tmp_path / "machine.dyr").write_text("1 'GENROU' 1 8 0.03 0.4 0.05 6.5 0 1.8 1.7 0.3 0.55 0.25 0.06 0 0 /\n")
    with pytest.raises(RecordError, match="no TGOV1, TGOV1D, IEEEG1, IEEEG1D, GGOV1, HYGOV, HYGOVD, GAST record; "
                                          "it holds GENROU"):
        read_record(tmp_path / "machine.dyr")
    (tmp_path / "two.dyr").write_text("1 'TGOV1' 1 0.05 0.5 1 0 2.5 7.5 0 /\n2 'TGOV1' 1 0.05 0.5 1 0 2.5 7.5 0 /\n")
    with pytest.raises(RecordError, match="several"):
        read_record(tmp_path / "two.dyr")
    assert read_record(tmp_path / "two.dyr", bus=2).line == 2


def test_bad_dyd_records():
    head = 'tgov1 1 "G" 20.0 "1" : #9 mva=100.0 '
    e = _error(pslf_dyd.parse_records, head + '"r" 0.05 "t1" 0.5 "vmax" 1 "vmin" 0 "t2" 2.5 "t3" 7.5 "dx" 0\n')
    assert (e.field, e.allowed) == ("dx", "r t1 vmax vmin t2 t3 dt")
    e = _error(pslf_dyd.parse_records, head + '"r" 0.05 "t1" 0.5\n')
    assert "misses vmax, vmin, t2, t3, dt" in str(e)
    e = _error(pslf_dyd.parse_records, head + '0.05 0.5 1 0 2.5 7.5\n')
    assert "takes 7 values, the record has 6" in str(e)
    e = _error(pslf_dyd.parse_records, head + '"r" 0.05 0.5 1 0 2.5 7.5 0\n')
    assert "mixes keyword and positional" in str(e)
    e = _error(pslf_dyd.parse_records, 'tgov1 x "G" 20.0 "1" : #9 mva=100.0 0.05 0.5 1 0 2.5 7.5 0\n')
    assert (e.field, e.value) == ("bus", "x")


def test_writing_checks_names_and_warns_for_a_dropped_sharpness_away_from_its_default():
    with pytest.raises(ParameterError, match="TGOV1 has no parameter K1"):
        psse_dyr.format_record("TGOV1", {"K1": 0.3}, bus=1)
    with pytest.raises(ParameterError, match="no record table for model 'WSIEG1'"):
        psse_dyr.format_record("WSIEG1", {}, bus=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, dropped = psse_dyr.format_record("TGOV1", {"p_ref": 0.83, "eps_v": 1e-4}, bus=1)  # no warning
    assert dropped == {"p_ref": 0.83, "eps_v": 1e-4}
    with pytest.warns(ExchangeWarning, match=r"TGOV1.K_lim = 1000 is not written \(default 100\)"):
        psse_dyr.format_record("TGOV1", {"K_lim": 1000.0}, bus=1)
    with pytest.raises(ParameterError, match="MVA base"):
        pslf_dyd.format_record("TGOV1", {}, bus=1, mva=None)
    numbers, _ = record_numbers(MODELS["IEEEG1"], {"T1": 0.001})
    assert dict((f.key, v) for f, v in numbers)["T1"] == 0.0  # PSS/E's "no lag"


# --- andes -------------------------------------------------------------------------------

GENERATOR_1 = (1, "1")  # bus 1, machine '1 ' of kundur.raw: 900 MVA on the 100 MVA system base


def _andes_system(record_text: str, tmp_path: Path):
    """Kundur's two-area case with ``record_text`` as generator 1's governor (its own
    TGOV1 removed from kundur_full.dyr)."""
    andes = pytest.importorskip("andes")
    andes.config_logger(stream_level=40, file=False, log_path=str(tmp_path))  # no /tmp/andes-* log per call
    full = Path(andes.get_case("kundur/kundur_full.dyr")).read_text()
    kept = [r for r in full.split("/") if r.strip() and not re.match(r"\s*1\s+'TGOV1'\s+1\s", r)]
    assert len(kept) == len([r for r in full.split("/") if r.strip()]) - 1
    dyr = tmp_path / "kundur_unit.dyr"
    dyr.write_text(" /\n".join(kept) + " /\n" + record_text)
    ss = andes.load(andes.get_case("kundur/kundur.raw"), addfile=str(dyr), setup=True, no_output=True,
                    default_config=True)
    assert ss is not None, "andes did not load the case with the exported record"
    return andes, ss


def _andes_outputs(andes, model: str) -> dict[str, str]:
    """andes' own map: its parameter name -> the .dyr column it comes from."""
    import yaml

    spec = yaml.safe_load((Path(andes.__file__).parent / "io" / "psse-dyr.yaml").read_text())[model]
    return {k: v for k, v in spec["outputs"].items() if k != "syn"}


@pytest.mark.parametrize("model", ["TGOV1", "IEEEG1", "GGOV1", "HYGOV", "GAST"])
def test_andes_reads_every_exported_dyr_value_and_runs_the_case(model, tmp_path):
    values = calibrated_values(model)
    text, _ = psse_dyr.format_record(model, values, bus=GENERATOR_1[0], machine_id=GENERATOR_1[1])
    written = [v for f, v in record_numbers(MODELS[model], values)[0] if f.psse]  # the .dyr's numbers, in order
    andes, ss = _andes_system(text, tmp_path)

    # andes' parser: every column it names, by its own field list (psse-dyr.yaml's inputs)
    parsed = ss.dyr_dict[model]
    assert len(parsed.columns) == 2 + len(MODELS[model].psse_fields)
    mine = parsed[parsed["BUS"] == GENERATOR_1[0]]
    assert len(mine) == 1
    row = mine.iloc[0]
    assert (int(row["BUS"]), int(row["ID"])) == (GENERATOR_1[0], int(GENERATOR_1[1]))
    aliases = {"BUS2": "JBUS", "ID2": "M", "FSWITCH": "FLAG"}  # andes' names of the same PSS/E fields
    by_column = dict(zip(parsed.columns[2:], written))
    for column, f in zip(parsed.columns[2:], MODELS[model].psse_fields):
        assert aliases.get(column.upper(), column.upper()) == f.psse.upper()
        assert float(row[column]) == by_column[column], column

    # the model andes builds from it: each value as given (vin), power quantities on the
    # system base (v): x Sn / Sb for power, x Sb / Sn for inverse power
    outputs = _andes_outputs(andes, model)
    destination = {"GGOV1": "TGOV1"}.get(model, model)  # andes 2.0 has no GGOV1: see the skip below
    device = getattr(ss, destination)
    generator = ss.GENROU.idx.v[list(ss.GENROU.bus.v).index(GENERATOR_1[0])]
    k = list(device.syn.v).index(generator)
    sn_over_sb = 900.0 / ss.config.mva
    for param, column in outputs.items():
        p = getattr(device, param)
        assert p.vin[k] == by_column[column], param
        coeff = sn_over_sb if p.get_property("power") else 1 / sn_over_sb if p.get_property("ipower") else 1.0
        assert p.v[k] == pytest.approx(p.vin[k] * coeff, rel=1e-12), param

    ss.PFlow.run()
    assert ss.PFlow.converged
    ss.TDS.config.tf = 2
    ss.TDS.config.no_tqdm = 1
    ss.TDS.run()
    assert ss.exit_code == 0 and ss.dae.t == pytest.approx(2.0)
    if model == "GGOV1":
        pytest.skip("andes 2.0 has no GGOV1 model: its psse-dyr.yaml reads all 35 GGOV1 fields (checked above) "
                    "but builds a TGOV1 with only R from them ('destination: TGOV1', marked TODO), so only R "
                    "reaches a simulation")


# --- in the product: export of an archive, a record as a config's documented constants ----

TGOV1_FIXED = {"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 5.0, "gov.VMAX": 0.95, "gov.T3": 6.0}


@pytest.fixture(scope="module")
def tgov1_run(fmus, tmp_path_factory):
    """A short calibration of a synthetic TGOV1 staged test (R and T1 estimated)."""
    import rapid_cosim as rc
    from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment

    work = tmp_path_factory.mktemp("export")
    t, y = synthesize(fmus["StagedTestTGOV1"], {**TGOV1_FIXED, "gov.R": 0.06, "gov.T1": 0.5}, duration=30.0,
                      noise=NoiseModel(white_sigma=0.0008), rng=np.random.default_rng(1))
    config = write_experiment(work / "step", model="iGrGen.TestBenches.StagedTestTGOV1", time=t, values=y,
                              fixed=TGOV1_FIXED, estimate={"gov.R": {"min": 0.02, "max": 0.12},
                                                           "gov.T1": {"min": 0.1, "max": 2.0}})
    fit = rc.calibrate(config, "nm", archive=work / "run.h5", options={"nm": {"max_fev": 40}})
    return work, config, fit


def test_export_writes_the_archived_calibration(tgov1_run):
    import rapid_cosim as rc
    from rapid_cosim.cli import main

    work, _, fit = tgov1_run
    written = rc.export(fit.archive, work / "unit.dyr", bus=5, machine_id="2")
    record = read_record(work / "unit.dyr")
    assert (written.model, record.bus, record.machine_id) == ("TGOV1", 5, "2")
    expected = {"R": fit.parameters["gov.R"], "T1": fit.parameters["gov.T1"], "VMAX": 0.95, "T3": 6.0,
                "VMIN": 0.0, "T2": 2.5, "Dt": 0.0}  # estimated, fixed, the bench's defaults
    assert record.values == expected
    assert main(["export", str(fit.archive), "--out", str(work / "unit.dyd"), "--mva", "110", "--bus", "5"]) == 0
    assert read_record(work / "unit.dyd").values == expected and read_record(work / "unit.dyd").mva == 110.0
    assert main(["export", str(fit.archive), "--out", str(work / "unit.dyd")]) == 2  # no --mva for a .dyd


def test_export_refuses_a_bench_without_a_standard_governor(fmus, tmp_path):
    import rapid_cosim as rc
    from conftest import synthetic_config

    from rapid_cosim.errors import ConfigError

    fit = rc.calibrate(synthetic_config(fmus["StagedTest"], tmp_path / "tg", seed=1), "nm",
                       archive=tmp_path / "tg.h5", options={"nm": {"max_fev": 10}})
    with pytest.raises(ConfigError, match="carries none of the standard governors"):
        rc.export(fit.archive, tmp_path / "unit.dyr")


def test_a_config_takes_its_documented_constants_from_a_record(tgov1_run, tmp_path):
    from rapid_cosim.structures.structure import Structure
    from rapid_cosim.errors import ConfigError
    from rapid_cosim.experiment import load_experiment, parse_experiment

    work, config, _ = tgov1_run
    record = {"R": 0.055, "T1": 0.4, "VMAX": 0.9, "VMIN": 0.1, "T2": 2.0, "T3": 5.5, "Dt": 0.2}
    psse_dyr.write_record(tmp_path / "unit.dyr", "TGOV1", record, bus=1)
    text = config.read_text()
    assert '"gov.T3" = 6.0' in text
    text = text.replace("[fixed]\n", f'[fixed]\ndocumented = "{tmp_path / "unit.dyr"}"  # the OEM data\n')
    (config.parent / "documented.toml").write_text(text)
    exp = load_experiment(config.parent / "documented.toml")
    assert {k: v for k, v in exp.fixed.items() if k.startswith("gov.")} == {
        "gov.p_ref": 0.6, "gov.VMAX": 0.95, "gov.T3": 6.0,  # stated in the config: kept
        "gov.VMIN": 0.1, "gov.T2": 2.0, "gov.Dt": 0.2}  # from the record; R and T1 stay estimated
    assert {s.name: s.start for s in exp.estimate} == {"gov.R": 0.055, "gov.T1": 0.4}  # the record's: starts
    assert not re.search(r"^documented", exp.config_text, re.M)
    assert "gov.R: 0.055 in the record, estimated here from it" in exp.config_text
    again = parse_experiment(exp.config_text, exp.config_path, data=exp.data)  # as from an archive: no record read
    assert (again.fixed, again.estimate) == (exp.fixed, exp.estimate)

    structure = tmp_path / "TGOV1.toml"
    structure.write_text((STRUCTURES / "TGOV1.toml").read_text().replace("[fixed]\n", '[fixed]\ndocumented = "unit.dyr"\n'))
    assert Structure.load(structure).fixed == {"gov.VMAX": 1.0, "gov.VMIN": 0.0, "gov.Dt": 0.0}  # stated: kept
    structure.write_text((STRUCTURES / "TGOV1.toml").read_text().replace(
        '"gov.VMAX" = 1.0\n"gov.VMIN" = 0.0\n"gov.Dt" = 0.0\n', 'documented = "unit.dyr"\n'))
    loaded = Structure.load(structure)
    assert loaded.fixed == {"gov.VMAX": 0.9, "gov.VMIN": 0.1, "gov.Dt": 0.2}
    assert {k: v.start for k, v in loaded.estimate.items()} == {"gov.R": 0.055, "gov.T1": 0.4,
                                                                       "gov.T2": 2.0, "gov.T3": 5.5}
    structure.write_text(structure.read_text().replace('"gov.R" =', "gov.R =").replace('"gov.T1" =', "gov.T1 ="))
    dotted = Structure.load(structure)  # dotted keys take the record's starts as quoted ones do
    assert (dotted.fixed, dotted.estimate) == (loaded.fixed, loaded.estimate)

    (tmp_path / "unit.dyr").write_text("1 'TGOV1' 1 0.05 0.5 one 0.0 2.5 7.5 0.0 /\n")
    with pytest.raises(ConfigError, match=r"\[fixed.documented\]: .*unit.dyr:1: field VMAX = 'one'"):
        load_experiment(config.parent / "documented.toml")


def test_a_deadband_goes_out_in_the_d_layout_and_reads_back_as_its_block(tmp_path):
    """TGOV1, IEEEG1 and HYGOV with a deadband are written as TGOV1D, IEEEG1D, HYGOVD (the
    plain fields, then dbH = db, dbL = -db, Trate 0), read back as their block with the
    same db; without one they keep their plain layout. An asymmetric band is refused with
    the value dbL should have."""
    for model in ("TGOV1", "IEEEG1", "HYGOV"):
        plain, _ = psse_dyr.format_record(model, {}, bus=4)
        assert f"'{model}'" in plain
        text, _ = psse_dyr.format_record(model, {"db": 0.0006}, bus=4)
        assert f"'{model}D'" in text and text.split()[-4:] == ["0.0006", "-0.0006", "0.0", "/"]
        (record,), _ = psse_dyr.parse_records(text)
        assert (record.model, record.block, record.values["db"], record.extra) == (f"{model}D", model, 0.0006,
                                                                                   {"Trate": 0.0})
        assert psse_dyr.format_record(model, record.values, bus=4, extra=record.extra)[0] == text
        (flat,), _ = psse_dyr.parse_records(plain)
        assert "db" not in flat.values and model_named(model).played(flat.values, {"gov.db": 0.001})["gov.db"] == 0.0
        assert "gov.db" not in model_named(model).played(flat.values, {"gov.p_ref": 0.6})  # a bench without one
    asymmetric = "1 'TGOV1D' 1 0.05 0.5 1 0 2.5 7.5 0 0.0006 -0.0004 0 /\n"
    e = _error(psse_dyr.parse_records, asymmetric)
    assert (e.field, e.value, e.allowed) == ("dbL", "-0.0004", "-0.0006") and "asymmetric band" in str(e)
    e = _error(psse_dyr.parse_records, "1 'TGOV1D' 1 0.05 0.5 1 0 2.5 7.5 0 0.02 -0.02 0 /\n")
    assert (e.field, e.allowed) == ("dbH", "0 to 0.01")


def test_gast_round_trips_in_both_formats(tmp_path):
    values = {"R": 0.04, "T1": 0.5, "T2": 0.15, "T3": 2.5, "AT": 0.95, "KT": 2.5, "VMAX": 1.1, "VMIN": -0.05,
              "Dt": 0.1}
    text, _ = psse_dyr.format_record("GAST", values, bus=9, machine_id="G1")
    (record,), _ = psse_dyr.parse_records(text)
    assert record.values == values and record.model == record.block == "GAST"
    dyd, _ = pslf_dyd.format_record("GAST", values, bus=9, machine_id="G1", mva=120.0)
    assert dyd.startswith("gast 9") and '"dturb" 0.1' in dyd
    (back,), _ = pslf_dyd.parse_records(dyd)
    assert back.values == values and back.mva == 120.0


def test_a_machine_whose_governor_is_of_another_model_is_told_apart(tmp_path):
    """A planning case's .dyr: a supported record for one machine, a WSIEG1 for another,
    and the machines and exciters beside them. The WSIEG1 machine's record is named as not
    supported (a fleet lists it); a machine with no governor at all is a plain error."""
    from rapid_cosim.exchange import UnsupportedRecord

    case = tmp_path / "case.dyr"
    case.write_text("1 'GENROU' 1 8 0.03 0.4 0.05 6.5 0 1.8 1.7 0.3 0.55 0.25 0.06 0 0 /\n"
                    "1 'TGOV1' 1 0.05 0.5 1 0 2.5 7.5 0 /\n"
                    "2 'GENROU' 1 8 0.03 0.4 0.05 6.5 0 1.8 1.7 0.3 0.55 0.25 0.06 0 0 /\n"
                    "2 'ESST1A' 1 1 1 0 0.02 0.2 /\n"
                    "2 'WSIEG1' 1 0 0 20 0 0 0.1 0.1 -0.1 1 0 0.3 0.3 0 7 0.7 0 0.5 0 0 0.05 0 0 0 0 0 /\n"
                    "3 'GENROU' 1 8 0.03 0.4 0.05 6.5 0 1.8 1.7 0.3 0.55 0.25 0.06 0 0 /\n")
    assert read_record(case, bus=1, machine_id="1").model == "TGOV1"
    with pytest.raises(UnsupportedRecord, match=r"case\.dyr:5: the record on file for bus 2 id 1 is WSIEG1: not "
                                                r"supported \(allowed: TGOV1, TGOV1D, .*GAST\)") as e:
        read_record(case, bus=2, machine_id="1")
    assert e.value.model == "WSIEG1"
    with pytest.raises(RecordError, match="none of its governor records match bus=3") as e:
        read_record(case, bus=3, machine_id="1")
    assert not isinstance(e.value, UnsupportedRecord)
    # another machine's record that cannot be read is that machine's problem, not this one's
    case.write_text(case.read_text() + "4 'TGOV1D' 1 0.05 0.5 1 0 2.5 7.5 0 0.0006 -0.0006 250 /\n")
    assert read_record(case, bus=1, machine_id="1").model == "TGOV1"
    with pytest.raises(RecordError, match=r"case\.dyr:7: field Trate = '250': TGOV1D on a turbine rating"):
        read_record(case, bus=4, machine_id="1")
    with pytest.raises(RecordError, match="Trate"):
        psse_dyr.parse_records(case.read_text(), str(case))  # read whole, a bad record is an error


def test_a_documented_band_is_a_constant_of_the_structure_not_a_part_to_free(tmp_path):
    """A structure file whose constants come from the unit's record: a TGOV1D's band is
    fixed as documented (and no longer freed); a plain TGOV1 record leaves it optional."""
    from rapid_cosim.structures.structure import Structure

    text = (STRUCTURES / "TGOV1.toml").read_text().replace("[fixed]\n", '[fixed]\ndocumented = "unit.dyr"\n')
    (tmp_path / "TGOV1.toml").write_text(text)
    psse_dyr.write_record(tmp_path / "unit.dyr", "TGOV1", {"R": 0.05, "VMAX": 0.95, "db": 0.0006}, bus=1)
    s = Structure.load(tmp_path / "TGOV1.toml")
    assert s.fixed["gov.db"] == 0.0006 and s.fixed["gov.VMAX"] == 1.0 and not s.optional  # stated values win
    psse_dyr.write_record(tmp_path / "unit.dyr", "TGOV1", {"R": 0.05, "VMAX": 0.95}, bus=1)
    s = Structure.load(tmp_path / "TGOV1.toml")
    assert "gov.db" not in s.fixed and set(s.optional) == {"gov.db"} and s.effects == ("deadband",)
