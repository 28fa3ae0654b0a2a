"""FMU builds: valid FMI 2.0, manifests, rebuilds only when something changed."""

import json
import shutil

import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from rapid_cosim.compiler import build_models, fmu_path, read_manifest, resolve_compiler
from rapid_cosim.compiler.openmodelica import find_omc
from rapid_cosim.errors import BuildError


def test_every_test_bench_fmu_validates(fmus):
    assert len(fmus) >= 8
    for name, path in fmus.items():
        assert validate_fmu(str(path)) == [], name


def test_parameters_are_tunable_and_carry_their_range(fmus):
    md = read_model_description(str(fmus["StagedTest"]))
    by_name = {v.name: v for v in md.modelVariables}
    r = by_name["gov.R"]
    assert (r.causality, r.variability) == ("parameter", "tunable")
    assert float(r.min) == 0.001 and float(r.max) == 1.0
    assert by_name["pm"].causality == "output"
    assert md.fmiVersion == "2.0" and md.modelExchange is not None


def test_manifest_and_rebuild_rules(tmp_path, repo, monkeypatch):
    monkeypatch.setenv("RAPID_COSIM_CACHE", str(tmp_path / "cache"))
    pkg = tmp_path / "iGrGen"
    shutil.copytree(repo / "modelica" / "iGrGen", pkg)
    out = tmp_path / "fmus"
    model = "iGrGen.TestBenches.StagedTest"
    first = build_models([model], package=pkg, fmu_dir=out, compiler="embedded", log=lambda *_: None)[0]
    assert first.rebuilt
    manifest = json.loads((out / f"{model}.manifest.json").read_text())
    assert manifest["compiler"] == "embedded" and manifest["fmi_version"] == "2.0"
    assert set(manifest["tools"]) >= {"pymoca", "casadi", "compiler"}
    assert len(manifest["source_hash"]) == 64

    again = build_models([model], package=pkg, fmu_dir=out, compiler="embedded", log=lambda *_: None)[0]
    assert not again.rebuilt

    f = pkg / "Governors" / "TGTypeI.mo"
    f.write_text(f.read_text().replace("// (3)", "// (3) edited"))
    edited = build_models([model], package=pkg, fmu_dir=out, compiler="embedded", log=lambda *_: None)[0]
    assert edited.rebuilt
    assert edited.manifest.source_hash != first.manifest.source_hash

    forced = build_models([model], package=pkg, fmu_dir=out, compiler="embedded", force=True, log=lambda *_: None)[0]
    assert forced.rebuilt

    fmu_path(model, out).write_bytes(b"corrupt")  # a tampered FMU is replaced (from the cache)
    fixed = build_models([model], package=pkg, fmu_dir=out, compiler="embedded", log=lambda *_: None)[0]
    assert not fixed.rebuilt
    assert read_manifest(fmu_path(model, out)).fmu_sha256 == edited.manifest.fmu_sha256


def test_another_folder_takes_the_cached_build_and_new_models_rebuild_nothing_else(tmp_path, repo, monkeypatch):
    monkeypatch.setenv("RAPID_COSIM_CACHE", str(tmp_path / "cache"))
    pkg = tmp_path / "iGrGen"
    shutil.copytree(repo / "modelica" / "iGrGen", pkg)
    model = "iGrGen.TestBenches.StagedTest"
    build = lambda folder: build_models([model], package=pkg, fmu_dir=tmp_path / folder,  # noqa: E731
                                        compiler="embedded", log=lambda *_: None)[0]
    first = build("a")
    assert first.rebuilt
    second = build("b")  # a fresh work folder, as a diagnosis makes
    assert not second.rebuilt
    assert fmu_path(model, tmp_path / "b").read_bytes() == fmu_path(model, tmp_path / "a").read_bytes()
    # another model in the package does not make this one stale
    bench = pkg / "TestBenches" / "StagedTestCopy.mo"
    bench.write_text((pkg / "TestBenches" / "StagedTest.mo").read_text().replace("StagedTest", "StagedTestCopy"))
    (pkg / "TestBenches" / "package.order").write_text(
        (pkg / "TestBenches" / "package.order").read_text() + "StagedTestCopy\n")
    assert not build("a").rebuilt


def test_auto_compiler_follows_omc(monkeypatch):
    assert resolve_compiler("auto") == ("openmodelica" if find_omc() else "embedded")
    with pytest.raises(BuildError, match="unknown compiler"):
        resolve_compiler("dymola")


@pytest.mark.openmodelica
@pytest.mark.skipif(find_omc() is None, reason="omc not found (OPENMODELICAHOME / PATH): OpenModelica backend not testable here")
def test_openmodelica_build_matches_embedded(tmp_path, repo, fmus):
    import numpy as np

    from rapid_cosim.simulator import Simulator

    out = tmp_path / "omc"
    model = "iGrGen.TestBenches.StagedTest"
    outcome = build_models([model], package=repo / "modelica" / "iGrGen", fmu_dir=out, compiler="openmodelica",
                           log=lambda *_: None)[0]
    assert outcome.manifest.compiler == "openmodelica"
    assert validate_fmu(str(outcome.fmu)) == []
    params = {"gov.Ts": 3.0, "gov.p_ref": 0.8, "src.t_return": 40.0}
    a = Simulator(outcome.fmu).simulate(params, stop_time=60, output_interval=0.05)
    b = Simulator(fmus["StagedTest"]).simulate(params, stop_time=60, output_interval=0.05)
    assert np.max(np.abs(a["pm"] - b["pm"])) < 1e-4


@pytest.mark.openmodelica
def test_openmodelica_compiler_without_omc_says_how_to_fix(monkeypatch, tmp_path, repo):
    monkeypatch.setenv("OPENMODELICAHOME", str(tmp_path / "nowhere"))
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(BuildError, match="omc not found"):
        build_models(["iGrGen.TestBenches.StagedTest"], package=repo / "modelica" / "iGrGen",
                     fmu_dir=tmp_path / "f", compiler="openmodelica", force=True, log=lambda *_: None)
