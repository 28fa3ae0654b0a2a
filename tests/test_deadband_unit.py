"""A unit with a frequency deadband gets a record that carries it (issue 53).

The plant is ANDES's TGOV1DB (experiments/deadband: R 0.05, T1 0.4, T2 1.5, T3 6, a
no-step band of +-0.0006 pu, 36 mHz at 60 Hz) in the Kundur grid, recorded in grid
events. Identified from events of two sizes (``unit.toml``), the explanation names the
deadband and the record is a TGOV1D whose droop and band are the plant's within 3 % and
10 %; the story says which layout carries it and what a plain TGOV1 loses, and no PSLF
record is written (PSLF's tgov1 has none). Identified from events of one size each way
(``one_size.toml``), the recordings do not determine the band: the record states none, and
the story says that its droop may have absorbed one (slow suite). The gas unit
(experiments/gas, ANDES's GAST) gets a GAST record (slow suite). ``make bench-replay``
puts each record back into ANDES.
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from rapid_cosim.cli import main
from rapid_cosim.exchange import read_record

REPO = Path(__file__).resolve().parents[1]
PLANT = {"R": 0.05, "db": 0.0006}


def _identify(unit: Path, results: Path) -> tuple[dict, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["identify", str(unit), "--results", str(results), "--n-jobs", "2", "--no-report",
                     "--fmus", str(REPO / "fmus")]) == 0
    return json.loads((results / "identification.json").read_text()), out.getvalue()


def test_a_deadband_unit_gets_a_record_that_carries_its_band(fmus, tmp_path):
    ident, story = _identify(REPO / "experiments" / "deadband" / "unit.toml", tmp_path)
    assert ident["explanation"]["effect"] == "deadband" and ident["explanation"]["adequate"]
    # the explanation's band, read on the events' own 60 Hz: the plant's 36 mHz within its interval
    lo, hi = ident["explanation"]["intervals"]["db.db"]
    assert lo < 0.036 < hi
    assert ident["recommended"] == "TGOV1"
    record = next(r for r in ident["records"] if r["model"] == "TGOV1")
    assert record["fit"] == "TGOV1+deadband" and record["optional_freed"] and record["undetermined"] == []
    written = read_record(tmp_path / "unit.dyr")
    assert (written.model, written.block) == ("TGOV1D", "TGOV1")
    assert written.values["R"] == pytest.approx(PLANT["R"], rel=0.03)
    assert written.values["db"] == pytest.approx(PLANT["db"], rel=0.10)
    assert "as TGOV1D (TGOV1's fields, then its deadband" in story and "loses the band" in story
    assert "PSLF's tgov1 has no deadband; the .dyr's TGOV1D record carries it" in story
    assert not (tmp_path / "unit.dyd").exists()


@pytest.mark.slow
def test_events_of_one_size_do_not_determine_the_band_and_the_story_says_so(fmus, tmp_path):
    ident, story = _identify(REPO / "experiments" / "deadband" / "one_size.toml", tmp_path)
    assert "deadband" in ident["explanation"]["not_excluded"]
    assert read_record(tmp_path / "unit.dyr").model == "TGOV1"  # no band stated ...
    record = next(r for r in ident["records"] if r["model"] == "TGOV1")
    assert record["undetermined"] == ["deadband"]  # ... the fleet's row flags it from this
    assert ("the recordings do not exclude a deadband of a material size, which TGOV1's db would carry, and do "
            "not determine one: the record states none; its droop may have absorbed a band") in story  # ... and said


@pytest.mark.slow
def test_a_gas_turbine_gets_a_gast_record(fmus, tmp_path):
    ident, _ = _identify(REPO / "experiments" / "gas" / "unit.toml", tmp_path)
    assert ident["recommended"] == "GAST"
    written = read_record(tmp_path / "unit.dyr")
    assert written.model == "GAST" and written.values["R"] == pytest.approx(0.05, rel=0.03)
    assert (tmp_path / "unit.dyd").read_text().startswith("gast 1 ")
