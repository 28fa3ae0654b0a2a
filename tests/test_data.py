"""rapid_cosim.data: loading, masking, time base, noise level."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from rapid_cosim.data import (MaskedSamplesWarning, MeasuredData, MissingColumn, load_measurements,
                              noise_level, sample_onto)
from rapid_cosim.errors import DataError

STAGED = Path("/work/shared/staged_tests")


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


# --------------------------------------------------------------------------- CSV

def test_csv_non_uniform_time_and_different_lengths(tmp_path):
    a = write(tmp_path / "a.csv", "time,pm\n0.0,0.60\n0.1013,0.61\n0.1990,0.62\n0.3021,0.63\n")
    b = write(tmp_path / "b.csv", "time , pm,pe\n0.0,0.8,0.79\n0.04,0.81,0.80\n")
    da, db = load_measurements(a), load_measurements(b)
    assert len(da) == 4 and len(db) == 2
    np.testing.assert_array_equal(da.time, [0.0, 0.1013, 0.1990, 0.3021])
    np.testing.assert_array_equal(da.columns["pm"], [0.60, 0.61, 0.62, 0.63])
    assert db.names == ("pm", "pe")  # header names are stripped
    assert da.gaps() == ()
    assert da.time.dtype == np.float64 and not da.time.flags.writeable


def test_csv_empty_and_nan_cells_are_masked_and_reported(tmp_path):
    p = write(tmp_path / "m.csv", "time,pm\n0,1\n1,\n2,nan\n3,4\n4,\n")
    with pytest.warns(MaskedSamplesWarning, match="3 in 'pm'"):
        d = load_measurements(p)
    np.testing.assert_array_equal(d.valid["pm"], [True, False, False, True, False])
    assert np.isnan(d.columns["pm"][1]) and d.n_valid("pm") == 2
    gaps = d.gaps("pm")
    assert [(g.start, g.end, g.n_samples, g.first_row, g.last_row) for g in gaps] == [
        (1.0, 2.0, 2, 3, 4), (4.0, 4.0, 1, 6, 6)]


def test_csv_bad_time_column_missing_lists_columns(tmp_path):
    p = write(tmp_path / "t.csv", "t,pm\n0,1\n")
    with pytest.raises(MissingColumn) as e:
        load_measurements(p)
    assert "no column 'time'" in str(e.value) and "t, pm" in str(e.value)
    assert e.value.file == str(p)


@pytest.mark.parametrize("rows, bad_row, word", [
    ("0,1\n0.1,1\n0.2,1\n0.3,1\n0.05,1\n", 6, "goes back from 0.3 s (row 5) to 0.05 s (row 6)"),  # 2.5 frames back
    ("0,1\n0.1,1\n0.1,2\n", 4, "written twice (rows 3 and 4) with different values (1 and 2)"),
    ("0,1\n,1\n0.2,1\n", 3, "missing"),
    ("0,1\nnan,1\n", 3, "missing"),
])
def test_csv_time_that_cannot_be_settled_names_rows(tmp_path, rows, bad_row, word):
    """A stamp more than a frame back (a clock reset), a repeated stamp whose values
    differ and a missing stamp are errors naming the rows; nothing is guessed."""
    p = write(tmp_path / "x.csv", "time,pm\n" + rows)
    with pytest.raises(DataError) as e:
        load_measurements(p)
    assert e.value.row == bad_row and e.value.file == str(p)
    assert word in str(e.value) and f"row {bad_row}" in str(e.value)


def test_repeated_and_late_stamps_are_settled_and_said(tmp_path):
    """A PDC's repeated frame (same values) is dropped and a frame one step late is sorted
    into place; both are said in a warning and kept in the time base's facts."""
    from rapid_cosim.data.timebase import TimeBaseWarning

    p = write(tmp_path / "x.csv", "time,pm\n0,1\n0.1,2\n0.1,2\n0.3,4\n0.2,3\n0.4,\n0.4,5\n")
    with pytest.warns(TimeBaseWarning) as w:
        data = load_measurements(p)
    assert np.array_equal(data.time, [0, 0.1, 0.2, 0.3, 0.4])
    assert np.array_equal(data.columns["pm"], [1, 2, 3, 4, 5])  # a blank copy takes the other's value
    assert list(data.rows) == [2, 3, 6, 5, 7]
    words = str(w[0].message)
    assert "2 repeated stamp(s) dropped" in words and "1 stamp(s) out of order sorted" in words
    base = data.timebase
    assert (base.repeated if hasattr(base, "repeated") else base.repairs.repeated) == 2
    assert base.repairs.reordered == 1 and "sorted" in base.describe()


def test_the_time_base_is_measured(tmp_path):
    """Jitter about the grid, frames missing and the holes they leave."""
    from rapid_cosim.data.timebase import inspect

    rng = np.random.default_rng(3)
    t = np.arange(0, 20, 0.02) + rng.uniform(-0.003, 0.003, 1000)
    keep = np.ones(1000, dtype=bool)
    keep[[100, 400, 401, 402, 403, 404]] = False
    base = inspect(t[keep])
    assert base.step == pytest.approx(0.02, rel=1e-3)
    assert base.dropped == 6 and base.longest_drop == 5 and len(base.holes) == 1
    assert 0.0015 < base.jitter_rms < 0.002 and base.jitter_max <= 0.0035
    assert not base.regular and inspect(np.arange(0, 1, 0.02).round(4)).regular


def test_csv_non_numeric_cell_names_row_column_and_value(tmp_path):
    p = write(tmp_path / "x.csv", "time,pm,pe\n0,1,2\n0.1,1,2\n0.2,abc,2\n")
    with pytest.raises(DataError) as e:
        load_measurements(p)
    assert e.value.row == 4
    assert "'pm'" in str(e.value) and "'abc'" in str(e.value)


def test_csv_wrong_field_count_is_an_error(tmp_path):
    p = write(tmp_path / "x.csv", "time,pm\n0,1\n0.1\n")
    with pytest.raises(DataError, match="expected 2 fields") as e:
        load_measurements(p)
    assert e.value.row == 3


def test_columns_mapping_selects_and_renames(tmp_path):
    p = write(tmp_path / "x.csv", "time,a,b\n0,1,2\n1,3,4\n")
    d = load_measurements(p, columns={"pm": "b"})
    assert d.names == ("pm",)
    np.testing.assert_array_equal(d.columns["pm"], [2, 4])
    with pytest.raises(MissingColumn, match="columns present: a, b"):
        load_measurements(p, columns={"pm": "c"})


def test_unknown_suffix_and_missing_file(tmp_path):
    with pytest.raises(DataError, match="unknown file type"):
        load_measurements(write(tmp_path / "x.xlsx", ""))
    with pytest.raises(DataError, match="file not found"):
        load_measurements(tmp_path / "nope.csv")


@pytest.mark.skipif(not (STAGED / "test6.csv").exists(), reason="staged test data not present")
def test_real_test6_recorder_gap_is_masked_and_reported():
    with pytest.warns(MaskedSamplesWarning, match="rows 1802-1864"):
        d = load_measurements(STAGED / "test6.csv")
    empty_rows = sum(1 for line in (STAGED / "test6.csv").read_text().splitlines()[1:]
                     if line.split(",")[1].strip() == "")
    assert empty_rows == 63
    assert len(d) == 2750 and d.n_valid("pm") == 2750 - empty_rows
    (gap,) = d.gaps("pm")
    assert gap.n_samples == 63 and (gap.first_row, gap.last_row) == (1802, 1864)
    assert gap.start == pytest.approx(72.0023) and gap.end == pytest.approx(74.479)
    assert "63 masked" in d.gap_report()
    assert np.all(np.diff(d.time) > 0)


# --------------------------------------------------------------------------- MAT, HDF5

def test_mat_round_trip_as_rapid_stores_it(tmp_path):
    t = np.linspace(0, 1, 11)
    sig = np.column_stack([np.sin(t), np.cos(t)])
    sig[3, 1] = np.nan
    scipy.io.savemat(tmp_path / "two.mat", {"time": t[:, None], "signal": sig})
    scipy.io.savemat(tmp_path / "one.mat", {"time": t, "signal": np.sin(t), "note": "x"})
    with pytest.warns(MaskedSamplesWarning):
        two = load_measurements(tmp_path / "two.mat")
    assert set(two.names) == {"signal_0", "signal_1"}
    np.testing.assert_allclose(two.time, t)
    np.testing.assert_allclose(two.columns["signal_0"], np.sin(t))
    assert not two.valid["signal_1"][3] and two.n_valid("signal_1") == 10
    one = load_measurements(tmp_path / "one.mat", columns={"pm": "signal"})
    np.testing.assert_allclose(one.columns["pm"], np.sin(t))
    with pytest.raises(MissingColumn, match="signal"):
        load_measurements(tmp_path / "one.mat", columns={"pm": "signal_0"})


def test_mat_v73_is_read_through_hdf5_transposed(tmp_path):
    t = np.linspace(0, 2, 21)
    sig = np.column_stack([t, 2 * t, 3 * t])  # MATLAB N x 3
    with h5py.File(tmp_path / "v73.mat", "w", userblock_size=512) as f:
        f["time"] = t[None, :]  # MATLAB column vector appears transposed
        f["signal"] = sig.T
        f["signal"].attrs["MATLAB_class"] = np.bytes_(b"double")
        f["name"] = np.frombuffer(b"test", dtype=np.uint8).astype(np.uint16)[:, None]
        f["name"].attrs["MATLAB_class"] = np.bytes_(b"char")
    d = load_measurements(tmp_path / "v73.mat")
    assert d.names == ("signal_0", "signal_1", "signal_2")
    np.testing.assert_allclose(d.columns["signal_2"], 3 * t)


def test_hdf5_root_and_group(tmp_path):
    t = np.array([0.0, 0.1, 0.25, 0.3])
    with h5py.File(tmp_path / "run.h5", "w") as f:
        f["time"] = t
        f["pm"] = [1.0, 2.0, np.nan, 4.0]
        g = f.create_group("tests/test1")
        g["time"] = t[:3]
        g["pm"] = [5.0, 6.0, 7.0]
        g["short"] = [1.0]
    with pytest.warns(MaskedSamplesWarning):
        root = load_measurements(tmp_path / "run.h5")
    assert root.names == ("pm",) and root.n_valid("pm") == 3
    sub = load_measurements(f"{tmp_path / 'run.h5'}:/tests/test1")
    np.testing.assert_array_equal(sub.columns["pm"], [5, 6, 7])
    with pytest.raises(MissingColumn, match="1 samples, time has 3"):
        load_measurements(f"{tmp_path / 'run.h5'}:/tests/test1", columns={"x": "short"})
    with pytest.raises(DataError, match="no group '/nope'.*/tests/test1"):
        load_measurements(f"{tmp_path / 'run.h5'}:/nope")


def test_hdf5_time_going_back_more_than_a_frame_rejected(tmp_path):
    with h5py.File(tmp_path / "bad.h5", "w") as f:
        f["time"] = [0.0, 1.0, 2.0, 0.5]
        f["pm"] = [1.0, 2.0, 3.0, 4.0]
    with pytest.raises(DataError, match="sample 4"):
        load_measurements(tmp_path / "bad.h5")


# --------------------------------------------------------------------------- windows

def test_window_restricts_samples_and_keeps_rows(tmp_path):
    p = write(tmp_path / "w.csv", "time,pm\n" + "".join(f"{i * 0.5},{i}\n" for i in range(10)))
    d = load_measurements(p).window(1.0, 2.5)
    np.testing.assert_array_equal(d.time, [1.0, 1.5, 2.0, 2.5])
    np.testing.assert_array_equal(d.rows, [4, 5, 6, 7])
    with pytest.raises(DataError, match="no samples"):
        d.window(10, 11)


def test_from_arrays_masks_non_finite_and_does_not_freeze_caller_arrays():
    t = np.array([0.0, 1.0, 2.0])
    y = np.array([1.0, np.inf, 3.0])
    d = MeasuredData.from_arrays(t, {"y": y})
    assert d.valid["y"].tolist() == [True, False, True] and np.isnan(d.columns["y"][1])
    t[0] = -1.0  # still writeable, and the data kept its own copy
    assert d.time[0] == 0.0


# --------------------------------------------------------------------------- sample_onto

def test_sample_onto_linear_interpolation_is_exact_for_lines():
    t_sim = np.linspace(0, 10, 501)
    y = np.column_stack([2 * t_sim + 1, -t_sim])
    t_meas = np.array([0.0, 0.0137, 3.33, 9.999, 10.0])
    out = sample_onto(t_sim, y, t_meas)
    np.testing.assert_allclose(out, np.column_stack([2 * t_meas + 1, -t_meas]), atol=1e-12)
    np.testing.assert_allclose(sample_onto(t_sim, y[:, 0], t_meas), 2 * t_meas + 1, atol=1e-12)


def test_sample_onto_takes_value_after_an_event():
    t_sim = np.array([0.0, 1.0, 1.0, 2.0])  # event at t = 1: value jumps 0 -> 5
    y = np.array([0.0, 0.0, 5.0, 5.0])
    np.testing.assert_array_equal(sample_onto(t_sim, y, [0.5, 1.0, 1.5]), [0.0, 5.0, 5.0])


def test_sample_onto_rejects_times_outside_the_simulation():
    t_sim = np.linspace(0, 10, 11)
    with pytest.raises(ValueError, match="not inside the simulated span"):
        sample_onto(t_sim, t_sim, [5.0, 10.5])
    with pytest.raises(ValueError, match="not inside"):
        sample_onto(t_sim, t_sim, [-0.1])
    # a rounding error at the end is not an error
    assert sample_onto(t_sim, t_sim, [10.0 + 1e-12])[0] == pytest.approx(10.0)


# --------------------------------------------------------------------------- noise

def _series(e: np.ndarray, phi: float, level=0.6, trend=0.0, dt=0.04):
    x = np.empty_like(e)
    x[0] = e[0] / np.sqrt(1 - phi ** 2)
    for i in range(1, e.size):
        x[i] = phi * x[i - 1] + e[i]
    t = np.arange(e.size) * dt + 1e-3 * np.sin(np.arange(e.size))  # jittered clock
    return MeasuredData.from_arrays(t, {"pm": level + trend * t + x})


def test_noise_level_white():
    rng = np.random.default_rng(1)
    d = _series(0.002 * rng.standard_normal(40_000), 0.0)
    est = noise_level(d, "pm", t_end=d.time[-1] + 1)
    assert est.sigma == pytest.approx(0.002, rel=0.02)
    assert abs(est.phi) < 0.02
    assert est.sigma_innovation == pytest.approx(0.002, rel=0.02)
    assert est.n == 40_000


def test_noise_level_ar1():
    rng = np.random.default_rng(2)
    phi, sigma_e = 0.8, 0.001
    d = _series(sigma_e * rng.standard_normal(40_000), phi)
    est = noise_level(d, "pm", t_end=d.time[-1] + 1)
    assert est.phi == pytest.approx(phi, rel=0.02)
    assert est.sigma_innovation == pytest.approx(sigma_e, rel=0.03)
    assert est.sigma == pytest.approx(sigma_e / np.sqrt(1 - phi ** 2), rel=0.05)


def test_noise_level_uses_only_pre_step_samples_and_detrends():
    rng = np.random.default_rng(3)
    d = _series(0.001 * rng.standard_normal(20_000), 0.0, trend=1e-4)
    t_end = d.time[10_000]
    y = d.columns["pm"].copy()
    y[10_000:] += 0.2  # the step must not leak into the estimate
    d = MeasuredData.from_arrays(d.time, {"pm": y})
    est = noise_level(d, "pm", t_end=t_end)
    assert est.n == 10_000
    assert est.sigma == pytest.approx(0.001, rel=0.03)
    flat = noise_level(d, "pm", t_end=t_end, detrend=False)
    assert flat.sigma > 2 * est.sigma  # the drift (4e-2 pu over the window) is not noise


def test_noise_level_gap_breaks_the_lag_pairs():
    # Alternating +-1 with every fourth sample masked: adjacent pairs all give -1, but
    # joining the samples either side of each gap would add (+1, +1) pairs (phi -1/3).
    y = np.array([1.0, -1.0] * 200)
    y[3::4] = np.nan
    d = MeasuredData.from_arrays(np.arange(400.0), {"y": y})
    est = noise_level(d, "y", t_end=1e9, detrend=False)
    assert est.n == 300
    assert est.phi == pytest.approx(-1.0, abs=0.05)


def test_noise_level_needs_samples():
    d = MeasuredData.from_arrays(np.arange(20.0), {"y": np.ones(20)})
    with pytest.raises(DataError, match="only 5 valid"):
        noise_level(d, "y", t_end=5.0)
    with pytest.raises(MissingColumn):
        noise_level(d, "pm", t_end=5.0)


def test_arrays_a_user_builds_wrongly_are_refused_with_their_source():
    """Issue 57: a DataError naming the recording, not a ValueError's traceback."""
    import pandas as pd

    from rapid_cosim import experiment_from_frame
    from rapid_cosim.data import MeasuredData
    from rapid_cosim.errors import DataError

    t = np.arange(3.0)
    with pytest.raises(DataError, match=r"my.csv: columns and valid need the same keys \(columns \['P'\], valid \[\]\)"):
        MeasuredData("my.csv", t, {"P": np.ones(3)}, {})
    with pytest.raises(DataError, match=r"my.csv: column 'P' is marked valid where it is not finite \(sample 2\)"):
        MeasuredData("my.csv", t, {"P": np.array([1.0, np.nan, 1.0])}, {"P": np.ones(3, dtype=bool)})
    frame = pd.DataFrame({"t": t, "P": np.ones(3)})
    with pytest.raises(DataError, match="unit1: the frame has no time column 'time'; columns: t, P"):
        experiment_from_frame("unit1", "iGrGen.TestBenches.StagedTest", frame)
    with pytest.raises(DataError, match=r"unit1: the frame has no column\(s\) Q"):
        experiment_from_frame("unit1", "iGrGen.TestBenches.StagedTest", frame, time="t", outputs={"pm": "Q"})
