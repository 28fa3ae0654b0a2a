"""Recorders' formats: COMTRADE (1999/2013, ASCII/binary), PMU CSV exports with absolute
timestamps, resampling, and bad files rejected with file, line or channel."""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np
import pytest

from rapid_cosim.data import load_measurements
from rapid_cosim.data.comtrade import write_comtrade
from rapid_cosim.data.pmu import parse_timestamp
from rapid_cosim.errors import DataError

START = datetime(2024, 3, 1, 12, 0, 0, tzinfo=timezone.utc)


def _signals(n=501, rate=50.0):
    t = np.arange(n) / rate
    return t, {"FREQ": 50.0 - 0.2 * (t > 3) + 0.001 * np.sin(7 * t), "P": 240.0 + 15 * np.tanh(t - 3)}


@pytest.mark.parametrize("revision", [1999, 2013])
@pytest.mark.parametrize("binary", [True, False])
def test_comtrade_round_trip_within_quantisation(tmp_path, revision, binary):
    t, ch = _signals()
    cfg = write_comtrade(tmp_path / "rec.cfg", t, ch, units={"FREQ": "Hz", "P": "MW"}, start=START,
                         revision=revision, binary=binary)
    data = load_measurements(cfg)
    np.testing.assert_allclose(data.time, t, atol=1e-6)
    for name, values in ch.items():
        step = (values.max() - values.min()) / 65000.0
        assert np.max(np.abs(data.columns[name] - values)) <= 0.51 * step + 1e-12
    assert data.names == ("FREQ", "P")


def test_comtrade_secondary_channel_scaled_to_primary(tmp_path):
    t, ch = _signals(n=11)
    cfg = write_comtrade(tmp_path / "rec.cfg", t, {"I": np.linspace(0, 5, 11)}, units={"I": "A"}, start=START)
    text = cfg.read_text().replace(",1,1,P", ",1000,5,S")  # a 1000:5 current transformer
    cfg.write_text(text)
    data = load_measurements(cfg)
    np.testing.assert_allclose(data.columns["I"], np.linspace(0, 5, 11) * 200.0, rtol=1e-4, atol=0.02)


def test_comtrade_dat_cut_short_names_both_counts(tmp_path):
    t, ch = _signals()
    cfg = write_comtrade(tmp_path / "rec.cfg", t, ch, units={}, start=START)
    dat = cfg.with_suffix(".dat")
    dat.write_bytes(dat.read_bytes()[:-120])
    with pytest.raises(DataError, match=r"rec\.dat holds 491 samples, the \.cfg announces 501"):
        load_measurements(cfg)


def test_comtrade_missing_dat_and_garbled_cfg(tmp_path):
    t, ch = _signals(n=20)
    cfg = write_comtrade(tmp_path / "rec.cfg", t, ch, units={}, start=START)
    cfg.with_suffix(".dat").rename(tmp_path / "other.dat")
    with pytest.raises(DataError, match="rec.dat is missing beside it"):
        load_measurements(cfg)
    bad = tmp_path / "bad.cfg"
    bad.write_text("STATION,DEV,1999\nthree,2A,1D\n")
    (tmp_path / "bad.dat").write_text("")
    with pytest.raises(DataError, match=r"bad\.cfg: the \.cfg does not follow C37\.111"):
        load_measurements(bad)


def test_comtrade_duplicate_channel_names_refused_by_channel(tmp_path):
    t, ch = _signals(n=20)
    cfg = write_comtrade(tmp_path / "rec.cfg", t, {"A": ch["P"], "B": ch["P"]}, units={}, start=START)
    cfg.write_text(cfg.read_text().replace("2,B,", "2,A,"))
    with pytest.raises(DataError, match="channel 2: the name 'A' is used twice"):
        load_measurements(cfg)


# --------------------------------------------------------------------------- PMU CSV


def test_pmu_csv_iso_timestamps_become_seconds_from_the_event(tmp_path):
    rows = ["timestamp,FREQ,P_MW"]
    for k in range(100):
        stamp = datetime.fromtimestamp(START.timestamp() + k * 0.02, tz=timezone.utc)
        rows.append(f"{stamp.isoformat().replace('+00:00', 'Z')},{50 - 0.001 * k},{240 + k}")
    path = tmp_path / "pmu.csv"
    path.write_text("\n".join(rows) + "\n")
    data = load_measurements(path, timestamp="timestamp", event_time="2024-03-01T12:00:01Z")
    np.testing.assert_array_equal(data.time, (np.arange(100) * 20_000 - 1_000_000) / 1e6)  # exact at 50 fps
    assert data.names == ("FREQ", "P_MW") and data.columns["P_MW"][99] == 339.0


def test_pmu_csv_epoch_seconds_and_zones_agree():
    assert parse_timestamp("1709294400.02") == parse_timestamp("2024-03-01T12:00:00.020Z")
    assert parse_timestamp("2024-03-01 13:00:00.02+01:00") == parse_timestamp("2024-03-01T12:00:00.02")
    with pytest.raises(ValueError, match="leap second"):
        parse_timestamp("2016-12-31T23:59:60Z")


@pytest.mark.parametrize("row, message", [
    ("2024-03-01T12:00:00.040Z,49.9,abc", r"row 4: column 'P': 'abc' is not a number"),
    ("yesterday,49.9,240", r"row 4: column 'ts': 'yesterday' is not a timestamp"),
    ("2024-03-01T12:00:00.000Z,49.9,240", r"row 4: column 'FREQ': time 0 s is written twice \(rows 2 and 4\)"),
    ("2024-03-01T12:00:00.040Z,49.9", r"row 4: expected 3 fields"),
])
def test_pmu_csv_bad_rows_named_by_row(tmp_path, row, message):
    path = tmp_path / "pmu.csv"
    path.write_text("ts,FREQ,P\n2024-03-01T12:00:00.000Z,50,240\n2024-03-01T12:00:00.020Z,50,240\n" + row + "\n")
    with pytest.raises(DataError, match=message):
        load_measurements(path, timestamp="ts")


def test_pmu_csv_missing_timestamp_column_suggests(tmp_path):
    path = tmp_path / "pmu.csv"
    path.write_text("time_utc,FREQ\n2024-03-01T12:00:00Z,50\n")
    with pytest.raises(DataError, match="time_utc"):
        load_measurements(path, timestamp="timestamp")


# --------------------------------------------------------------------------- resampling


def test_resample_interpolates_and_masks_around_invalid_samples(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("time,a\n0,0\n1,10\n2,\n3,30\n4,40\n")
    with pytest.warns(Warning):
        data = load_measurements(path)
    out = data.resample([0.0, 0.5, 1.0, 1.5, 3.0, 3.5, 4.0])
    np.testing.assert_array_equal(out.valid["a"], [True, True, True, False, True, True, True])
    np.testing.assert_allclose(out.columns["a"][out.valid["a"]], [0, 5, 10, 30, 35, 40])
    with pytest.raises(DataError, match="inside the record"):
        data.resample([0.0, 5.0])
