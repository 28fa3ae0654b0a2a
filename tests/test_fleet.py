"""A fleet (issue 34) at a small size: a right record on file passes and is kept, a wrong
one is flagged and the unit identified (by rapid-cosim identify's own function), bad
units get rows with their errors and the rest complete, a rerun keeps every finished
unit, the page sorts in headless Chromium, and a worker killed mid-fleet on a real dask
cluster leaves every unit's result bit for bit. ``make bench-fleet`` runs 100 units."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from rapid_cosim.errors import ConfigError
from rapid_cosim.experiment import EstimateSpec
from rapid_cosim.fleet import Route, load_fleet, run_fleet
from rapid_cosim.fleet.synthetic import draw_unit, make_fleet

from test_dask_cluster import Cluster
from rapid_cosim.fitting.engine import EngineSpec
from rapid_cosim.compiler.source import ModelSource

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
UNITS = [0, 5]  # a TGOV1 unit whose record is right (P_e), a TGOV1 unit whose record's T3 is twice the plant's


def _bad_units(folder: Path) -> None:
    """A unit whose config names a column its data lacks, one whose data file is not
    numbers, one whose record on file is not a record."""
    for name, edit in (("bad_config", lambda u: _replace(u / "event" / "config.toml", 'column = "P"',
                                                         'column = "POWER"')),
                       ("bad_data", lambda u: (u / "event" / "data.csv").write_text("time,FREQ,P\n0,x,1\n")),
                       ("bad_record", lambda u: (u / "record.dyr").write_text("1 'IEEEG1' 1 oops /\n"))):
        unit = folder / "units" / name
        shutil.copytree(folder / "units" / "unit000", unit)
        edit(unit)


def _replace(path: Path, old: str, new: str) -> None:
    path.write_text(path.read_text().replace(old, new))


@pytest.fixture(scope="module")
def fleet(fmus, repo, tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet")
    spec = make_fleet(folder, UNITS, experiments=repo / "experiments", seed=1, source=ModelSource(fmu_dir=repo / "fmus"))
    _bad_units(folder)
    t0 = time.perf_counter()
    result = run_fleet(spec, results=folder / "results", engine=EngineSpec(n_jobs=2, backend="dask"), progress=False, log=lambda *_: None,
                       source=ModelSource(package=repo / "modelica" / "iGrGen", fmu_dir=repo / "fmus"))
    return folder, spec, result, time.perf_counter() - t0


def test_right_records_pass_wrong_ones_are_identified_and_bad_units_fail_alone(fleet):
    folder, spec, result, _ = fleet
    rows = {u.unit: u for u in result.units}
    assert draw_unit(0, 1).record_right and not draw_unit(5, 1).record_right and draw_unit(5, 1).wrong == "lag"
    assert rows["unit000"].route is Route.PASSED and rows["unit000"].on_file.passed
    wrong = rows["unit005"]
    assert wrong.route is Route.IDENTIFIED and not wrong.on_file.passed
    assert wrong.recommended.playback.passed, wrong.flags  # the new record passes its bands and the noise tests
    results = folder / "results"
    assert (results / wrong.files["dyr"]).is_file() and (results / wrong.files["report"]).is_file()
    assert rows["bad_config"].route is Route.FAILED and "no column 'POWER'" in rows["bad_config"].error
    assert rows["bad_data"].route is Route.FAILED and "'x' is not a number" in rows["bad_data"].error
    assert rows["bad_record"].route is Route.FAILED and "record.dyr" in rows["bad_record"].error
    assert result.failed == 3


def test_the_fleet_report_lists_failing_units_first_and_holds_every_new_record(fleet):
    folder, spec, result, _ = fleet
    table = (folder / "results" / "fleet.csv").read_text().splitlines()
    order = [line.split(",")[0] for line in table[1:]]
    assert order[:3] == ["bad_config", "bad_data", "bad_record"] and order[-1] == "unit000"
    data = json.loads((folder / "results" / "fleet.json").read_text())
    assert data["failed"] == 3 and len(data["units"]) == 5
    records = (folder / "results" / "fleet.dyr").read_text()
    assert records.count("'TGOV1'") + records.count("'IEEEG1'") == 1 and " 105 " in f" {records}"


def test_a_wrong_record_inside_every_band_is_flagged_by_the_noise_tests(fmus, repo, tmp_path):
    """Unit 98's record has HYGOV's water time constant twice the plant's: its playback
    passes every band (an RMSE of 2 noise levels on P_e, where right records leave 1.1
    to 2), and the noise tests reject it (with 30 s before the event, its residual's
    variance; the score test's naming is tested in test_adequacy_null). The right record
    of unit 0 passes both, with its bands' stated false-alarm rate; unit 64's (TG Type I)
    is not said to want its steam chest below its floor. Unit 70's right
    record has a marginal overshoot, whose time to peak the noise alone fails more than
    one time in ten: not judged, and said."""
    from rapid_cosim.exchange import read_record
    from rapid_cosim.experiment import load_experiment
    from rapid_cosim.fleet.playback import UNJUDGEABLE, play_back
    from rapid_cosim.identify import Unit
    from rapid_cosim.validation.tolerances import Tolerances

    make_fleet(tmp_path, [0, 64, 70, 98], experiments=repo / "experiments", seed=1, source=ModelSource(fmu_dir=repo / "fmus"))
    assert draw_unit(98, 1).wrong == "lag" and draw_unit(98, 1).structure == "HYGOV"
    out = {}
    for name in ("unit000", "unit064", "unit070", "unit098"):
        unit = Unit.load(tmp_path / "units" / name)
        record = read_record(tmp_path / "units" / name / "record.dyr", bus=unit.bus, machine_id=unit.machine_id)
        out[name] = play_back(record, [load_experiment(c) for c in unit.configs], list(unit.structures),
                              Tolerances(), source=ModelSource(package=repo / "modelica" / "iGrGen", fmu_dir=repo / "fmus"))
    wrong, right = out["unit098"], out["unit000"]
    assert all(t.passed for t in wrong.tests.values()) and not wrong.passed
    assert wrong.p < 0.01 and wrong.inconsistent
    assert right.passed and right.p > 0.05 and not right.inconsistent
    assert right.false_alarm < 0.2 and right.false_alarm >= 0.01  # the noise tests' 1 % at least
    # A right TG Type I record: its 1 ms steam chest sits on IEEEG1's T4 floor, and the data
    # pull it below; the constrained score test leaves it out (it was named, going to -0.024 s).
    assert draw_unit(64, 1).record_right and draw_unit(64, 1).structure == "TGTypeI"
    assert not any("T4" in why for why in out["unit064"].inconsistent), out["unit064"].inconsistent
    marginal = out["unit070"]
    assert draw_unit(70, 1).record_right and marginal.passed
    assert marginal.tests["unit070"].not_judged["time_to_peak"] > UNJUDGEABLE


def test_the_fleets_new_record_is_what_rapid_cosim_identify_delivers(fleet, repo, tmp_path):
    """The wrong record's unit identified by the CLI, as an engineer would run it alone:
    the same record, byte for byte, and the same explanation."""
    folder, spec, result, _ = fleet
    row = next(u for u in result.units if u.unit == "unit005")
    proc = subprocess.run([sys.executable, "-m", "rapid_cosim.cli", "identify", str(folder / "units" / "unit005"),
                           "--results", str(tmp_path), "--no-pdf", "--seed", "1"], capture_output=True, text=True,
                          timeout=900, cwd=repo)
    assert proc.returncode == 0, proc.stderr[-2000:]
    fleet_dyr = (folder / "results" / row.files["dyr"]).read_text()
    assert (tmp_path / Path(row.files["dyr"]).name).read_text() == fleet_dyr
    assert row.explanation in proc.stdout


def test_a_rerun_keeps_every_finished_unit_and_redoes_a_changed_one(fleet, tmp_path):
    folder, spec, result, first = fleet
    t0 = time.perf_counter()
    again = run_fleet(spec, results=folder / "results", engine=EngineSpec(n_jobs=1, backend="dask"), progress=False, log=lambda *_: None)
    assert not again.ran and sorted(again.kept) == sorted(u.unit for u in result.units)
    assert [u for u in again.units] == [u for u in result.units]
    assert time.perf_counter() - t0 < first  # no unit was run again
    _replace(folder / "units" / "bad_config" / "event" / "config.toml", 'column = "POWER"', 'column = "P"')
    fixed = run_fleet(spec, results=folder / "results", engine=EngineSpec(n_jobs=1, backend="dask"), progress=False, log=lambda *_: None)
    assert fixed.ran == ["bad_config"] and fixed.failed == 2


def test_the_cli_exit_status_says_how_many_units_failed(fleet):
    folder, spec, result, _ = fleet
    proc = subprocess.run([sys.executable, "-m", "rapid_cosim.cli", "fleet", str(spec), "--results",
                           str(folder / "results"), "--quiet"], capture_output=True, text=True, timeout=600,
                          cwd=Path(__file__).resolve().parents[1])
    failed = json.loads((folder / "results" / "fleet.json").read_text())["failed"]
    assert proc.returncode == (100 + failed if failed else 0), proc.stderr
    assert "records on file pass" in proc.stdout and "fleet.html" in proc.stdout


def test_a_planning_cases_records_are_matched_by_bus_and_id_and_other_families_listed(fleet, tmp_path):
    """One .dyr holding the case's records (machines, exciters, governors of several
    families) for every unit: each unit's record is found by its bus and machine id; a
    unit whose governor is of a model no table reads (WSIEG1) is a row saying so, not
    checked and not identified, and the fleet goes on; the CSV, the page and the summary
    count it apart from the failures (issue 53)."""
    folder, spec, result, _ = fleet
    case = []
    for name in ("unit000", "unit005"):
        shutil.copytree(folder / "units" / name, tmp_path / "units" / name)
        own = tmp_path / "units" / name / "record.dyr"
        case.append(own.read_text())
        bus = own.read_text().split()[0]
        case.append(f"{bus} 'GENROU' 1 8 0.03 0.4 0.05 6.5 0 1.8 1.7 0.3 0.55 0.25 0.06 0 0 /\n")
        own.unlink()
    other = tmp_path / "units" / "unit_wsieg1"
    shutil.copytree(folder / "units" / "unit000", other)
    (other / "record.dyr").unlink()
    _replace(other / "unit.toml", "bus = 100", "bus = 777")
    case += ["777 'GENROU' 1 8 0.03 0.4 0.05 6.5 0 1.8 1.7 0.3 0.55 0.25 0.06 0 0 /\n",
             "777 'ESST1A' 1 1 1 0 0.02 0.2 /\n",
             "777 'WSIEG1' 1 0 0 20 0 0 0.1 0.1 -0.1 1 0 0.3 0.3 0 7 0.7 0 0.5 0 0 0.05 0 0 0 0 0 /\n"]
    (tmp_path / "case.dyr").write_text("".join(case))
    (tmp_path / "fleet.toml").write_text('[fleet]\nname = "a planning case"\nunits = ["units/*"]\n'
                                         'records = "case.dyr"\n')
    assert "bus = 100" in (folder / "units" / "unit000" / "unit.toml").read_text()
    checked = run_fleet(tmp_path / "fleet.toml", results=tmp_path / "results", engine=EngineSpec(n_jobs=1),
                        check_only=True, progress=False, log=lambda *_: None,
                        source=ModelSource(fmu_dir=Path(__file__).resolve().parents[1] / "fmus"))
    rows = {u.unit: u for u in checked.units}
    assert rows["unit000"].route is Route.PASSED and rows["unit005"].route is Route.FAILS
    assert rows["unit000"].on_file.source.endswith("case.dyr")
    listed = rows["unit_wsieg1"]
    assert listed.route is Route.UNSUPPORTED and listed.unsupported == "WSIEG1" and listed.on_file is None
    assert listed.flags == ["record on file is WSIEG1: not supported"] and not listed.files
    assert checked.failed == 0 and checked.count(Route.UNSUPPORTED) == 1
    assert "1 not checked (their records on file of a model not supported)" in checked.summary()
    table = (tmp_path / "results" / "fleet.csv").read_text().splitlines()
    assert any(line.startswith("unit_wsieg1,record on file not supported,WSIEG1,") for line in table)
    page = (tmp_path / "results" / "fleet.html").read_text()
    assert "record on file is WSIEG1: not supported" in page and "1 not checked" in page


def _busiest(workers):
    import psutil

    before = [sum(psutil.Process(w.pid).cpu_times()[:2]) for w in workers]
    time.sleep(1.0)
    used = [sum(psutil.Process(w.pid).cpu_times()[:2]) - b for w, b in zip(workers, before)]
    return workers[used.index(max(used))]


def test_bad_fleet_files_are_named(tmp_path):
    (tmp_path / "a.toml").write_text("[fleet]\nunits = []\n")
    with pytest.raises(ConfigError, match=r"fleet.units.*a list of unit folders"):
        load_fleet(tmp_path / "a.toml")
    (tmp_path / "b.toml").write_text('[fleet]\nunits = ["nowhere/*"]\n')
    with pytest.raises(ConfigError, match=r"'nowhere/\*' names no unit folder"):
        load_fleet(tmp_path / "b.toml")
    (tmp_path / "c.toml").write_text('[fleet]\nunit = ["x"]\n')
    with pytest.raises(ConfigError, match=r"unknown key\(s\) unit"):
        load_fleet(tmp_path / "c.toml")


@pytest.mark.skipif(CHROMIUM is None, reason="needs Chromium (Debian package 'chromium'; .ci/run installs it)")
def test_the_page_sorts_in_headless_chromium(fleet):
    from rapid_cosim.report.pdf import QUIET

    folder, *_ = fleet
    page = folder / "results" / "fleet.html"
    probe = page.with_name("probe.html")
    check = ("<script>const h = document.querySelectorAll('#fleet th'); h[0].click(); h[1].click();"
             "const names = [...document.querySelectorAll('#fleet tbody tr')].map(r => r.cells[0].textContent);"
             "const p = document.createElement('p'); p.id = 'so' + 'rted'; p.textContent = names.join(',');"
             "document.body.appendChild(p);</script>")
    probe.write_text(page.read_text().replace("</body>", check + "\n</body>"))
    with tempfile.TemporaryDirectory() as profile:
        dom = subprocess.run([CHROMIUM, *QUIET, f"--user-data-dir={profile}", "--virtual-time-budget=5000",
                              "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=120).stdout
    order = re.search(r'<p id="sorted">([^<]*)</p>', dom)
    assert order, dom[-1500:]
    shown = order.group(1).split(",")
    # by name, then by route (a stable sort): the failing units first, then the identified, then the passing
    rows = json.loads((folder / "results" / "fleet.json").read_text())["units"]
    order = {"failed": 0, "identified": 1, "record on file passes": 2}
    assert shown == [r["unit"] for r in sorted(rows, key=lambda r: (order[r["route"]], r["unit"]))], shown
    assert shown[0].startswith("bad_") and shown[-1].startswith(("unit000", "bad_config"))


def _blas_threads(address: str) -> set[int]:
    from distributed import Client

    def pools():
        from threadpoolctl import threadpool_info

        return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]

    with Client(address, timeout=30) as client:
        return {n for found in client.run(pools).values() for n in found}


def test_a_killed_worker_leaves_every_units_result_bit_for_bit(fleet, tmp_path, repo):
    """On a real cluster (scheduler and two bare workers, ``dask worker --no-nanny``,
    their BLAS pools at one thread a core where the local cluster's nanny sets 1), a
    worker SIGKILLed while it identifies a unit: the fleet finishes, and every unit's
    result is the local run's, byte for byte (issue 43: 9 units of 12 differed before a
    unit's threads were pinned)."""
    folder, spec, result, _ = fleet
    cores = os.cpu_count() or 1
    cluster = Cluster(tmp_path, threads=cores)
    try:
        assert _blas_threads(cluster.address) == {cores}  # on 2 cores or more, not the local run's setting
        out = tmp_path / "results"
        proc = subprocess.Popen([sys.executable, "-m", "rapid_cosim.cli", "fleet", str(spec), "--results", str(out),
                                 "--scheduler", cluster.address, "--quiet"], cwd=repo, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        deadline = time.time() + 300
        while time.time() < deadline and not (out / "units" / "unit005" / "records").exists():
            time.sleep(0.2)  # the wrong record's unit is being identified
        time.sleep(3.0)
        os.kill(_busiest(cluster.workers).pid, signal.SIGKILL)  # the worker identifying it
        stdout, stderr = proc.communicate(timeout=900)
    finally:
        cluster.close()
    failed = json.loads((out / "fleet.json").read_text())["failed"]
    assert proc.returncode == 100 + failed and failed >= 2, stderr
    for path in sorted((folder / "results" / "units").glob("*.json")):  # the local run's, as the fleet stands
        local = json.loads(path.read_text())
        again = json.loads((out / "units" / path.name).read_text())
        mine = {k: v for k, v in local.items() if k != "seconds"}
        theirs = {k: v for k, v in again.items() if k != "seconds"}
        assert theirs == mine, path.stem
    delivered = sorted((folder / "results" / "units").glob("*/unit.dyr"))  # the records delivered
    assert [d.parent.name for d in delivered] == ["unit005"]
    for dyr in delivered:
        assert (out / "units" / dyr.parent.name / "unit.dyr").read_bytes() == dyr.read_bytes(), dyr.parent.name


def test_checking_only_identifies_nothing_and_a_short_quiet_span_is_flagged(fmus, repo, tmp_path):
    """``check_only``: the wrong record's row says it fails, with nothing identified; a
    unit with no record on file is a failed row that says why. The units recorded with
    ANDES's own 10 s before the event carry a flag saying the noise tests are weaker
    there; the same units with 30 s carry none."""
    spec = make_fleet(tmp_path, [5], experiments=repo / "experiments", seed=1, source=ModelSource(fmu_dir=repo / "fmus"),
                      pre_event=10.0)
    shutil.copytree(tmp_path / "units" / "unit005", tmp_path / "units" / "no_record")
    (tmp_path / "units" / "no_record" / "record.dyr").unlink()
    result = run_fleet(spec, results=tmp_path / "results", engine=EngineSpec(n_jobs=1, backend="dask"), progress=False, log=lambda *_: None,
                       source=ModelSource(package=repo / "modelica" / "iGrGen", fmu_dir=repo / "fmus"), check_only=True)
    rows = {u.unit: u for u in result.units}
    wrong = rows["unit005"]
    assert wrong.route is Route.FAILS and wrong.recommended is None and not wrong.files
    assert not (tmp_path / "results" / "fleet.dyr").exists()
    assert any(f.startswith("under 30 s before the event (unit005: 10.0 s)") for f in wrong.flags), wrong.flags
    assert rows["no_record"].route is Route.FAILED and "no record on file" in rows["no_record"].error
    page = (tmp_path / "results" / "fleet.html").read_text()
    assert "1 records on file pass" not in page and "0 records on file pass, 1 fail (checked only" in page
    assert "<tr class=fails><td>unit005</td>" in page and "<tr class=failed><td>no_record</td>" in page
    ok = run_fleet(make_fleet(tmp_path / "long", [5], experiments=repo / "experiments", seed=1,
                              source=ModelSource(fmu_dir=repo / "fmus")), results=tmp_path / "r30",
                   engine=EngineSpec(n_jobs=1, backend="dask"), progress=False, log=lambda *_: None, source=ModelSource(package=repo / "modelica" / "iGrGen", fmu_dir=repo / "fmus"), check_only=True)
    assert ok.units[0].route is Route.FAILS and ok.units[0].flags == []


def test_a_tie_is_flagged_from_the_identifications_fields_whole():
    from rapid_cosim.fleet.unit_job import tie_flag

    # the recommendation's sentence has a ';' inside its parentheses: a flag cut from it
    # read "tie: first by BIC (IEEEG1, 7 estimated parameters"
    assert tie_flag("TGOV1", "IEEEG1", ["TGOV1"]) == "tie: TGOV1 recommended, tying with IEEEG1 (the first by BIC)"
    assert tie_flag("IEEEG1", None, ["TGOV1"]) == ("tie: IEEEG1 recommended (the first by BIC), TGOV1 tying with "
                                                   "it but passed over")


def test_a_parameter_on_its_bound_pulled_outward_is_held_out_of_the_score_test():
    """The constrained score test: a record's value on its structure's bound is the
    optimum there when the data pull it further out, so that parameter leaves the test;
    pulled inward, or off the bound, it stays."""
    from types import SimpleNamespace

    import numpy as np

    from rapid_cosim.fleet.playback import _held_at_bounds

    structure = SimpleNamespace(estimate={"gov.T4": EstimateSpec("gov.T4", 0.001, 10.0, "T4"),
                                          "gov.K": EstimateSpec("gov.K", 8.0, 50.0, "K")})
    names, x = ["gov.K", "gov.T4"], np.array([50.0, 0.001])
    pulled = lambda *alone: SimpleNamespace(alone=alone)  # noqa: E731
    assert _held_at_bounds(x, names, [0, 1], structure, pulled(0.3, -0.02)) == [0, 1]
    assert _held_at_bounds(x, names, [0, 1], structure, pulled(-0.3, 0.02)) == []
    assert _held_at_bounds(np.array([20.0, 0.5]), names, [0, 1], structure, pulled(0.3, -0.6)) == []
    assert _held_at_bounds(x, names, [1], structure, pulled(-0.02)) == [1]  # columns follow the kept parameters
