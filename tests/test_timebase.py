"""Recordings as recorders write them (issue 31): the ROCOF fitted on the stamps as
recorded, its noise whitened exactly on them, quality flags and impossible values masked,
and every bad input named by file, column and rows."""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy import linalg
from scipy.signal import savgol_filter

from rapid_cosim.errors import ConfigError, DataError
from rapid_cosim.experiment import load_experiment
from rapid_cosim.noise import RecorderNoise
from rapid_cosim.noise.filtered import FilteredNoise, LevinsonWhitener
from rapid_cosim.noise.timed import DerivedNoise, TimedWhitener, dense_covariance
from rapid_cosim.noise.whitening import Whitening
from rapid_cosim.simulator.rocof import noise_gain, points, rocof_operator

REPO = Path(__file__).resolve().parents[1]
EVENT = REPO / "experiments" / "electrical" / "tgov1_on"
DT = 1 / 30


def _jittered(n=600, jitter=0.003, drop=(), seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT + rng.uniform(-jitter, jitter, n)
    return np.delete(t, list(drop))


# --------------------------------------------------------------------------- the ROCOF


def test_on_regular_stamps_the_rocof_is_the_savitzky_golay_derivative():
    t = np.arange(0, 30, DT)
    f = np.random.default_rng(1).standard_normal(t.size)
    n = points(DT)
    cut = int(np.searchsorted(t, 10.0, side="right"))
    expected = np.concatenate([savgol_filter(f[:cut], n, 2, deriv=1, delta=DT, mode="interp"),
                               savgol_filter(f[cut:], n, 2, deriv=1, delta=DT, mode="interp")])
    assert np.max(np.abs(rocof_operator(t, breaks=(10.0,)).apply(f) - expected)) < 1e-10


def test_on_jittered_and_gappy_stamps_the_rocof_is_exact_on_a_quadratic():
    """No raw difference anywhere: the local fit holds its samples' true times, a missing
    frame is simply absent, masked samples are left out of the windows."""
    t = _jittered(drop=(100, 200, 201, 202, 203, 204))
    valid = np.ones(t.size, dtype=bool)
    valid[[300, 301]] = False
    f = 0.3 * t ** 2 - t
    f[~valid] = 0.0  # what an invalid frame carries: it must not matter
    op = rocof_operator(t, valid=valid)
    assert not op.unfit.any()
    assert np.max(np.abs(op.apply(f) - (0.6 * t - 1))) < 1e-9
    assert np.all(np.diff(op.matrix.indptr) >= 4)  # every row a local fit, never a two-point difference
    gain = np.sqrt(np.asarray(op.matrix.multiply(op.matrix).sum(axis=1)).ravel())
    assert np.median(gain) == pytest.approx(noise_gain(DT), rel=0.05)


def test_a_window_that_cannot_hold_a_fit_is_named_and_its_power_left_out(tmp_path):
    """Two seconds of frequency marked invalid: the ROCOF windows inside hold no sample, so
    their P_e samples leave the fit and the recording says where."""
    folder = _copy_event(tmp_path)
    rows = (folder / "data.csv").read_text().splitlines()
    for k in range(601, 661):  # 20.0 s to 22.0 s
        time, _, power = rows[k].split(",")
        rows[k] = f"{time},,{power}"
    (folder / "data.csv").write_text("\n".join(rows) + "\n")
    config = folder / "config.toml"
    config.write_text(config.read_text().replace('baseline = "pre-event" }',
                                                 'baseline = "pre-event", gaps = { max = 2.5 } }'))
    with pytest.warns(Warning):
        exp = load_experiment(config)
    assert exp.recording.unfit and "could not hold a fit" in exp.recording.lines()[-1]
    t, ok = exp.data.time, exp.data.valid["P"]
    assert not ok[(t > 20.3) & (t < 21.7)].any()  # in the hole: no ROCOF
    assert ok[(t > 14.5) & (t < 19.5)].all() and ok[t > 26.5].all()


# --------------------------------------------------------------------------- its noise


@pytest.mark.parametrize("source", [RecorderNoise(0.3e-3, ((0.9e-3, 0.15),), DT), RecorderNoise(1e-3, (), DT)])
def test_the_timed_whitening_is_the_exact_covariances_inverse_cholesky_factor(source):
    """Jittered stamps, missing frames, masked samples, the derived ROCOF's noise through
    its own map: W Sigma W' = I, W the inverse of Sigma's Cholesky factor."""
    t = _jittered(n=300, drop=(40, 41, 42, 150))
    model = RecorderNoise(0.9e-3, ((1.2e-3, 0.6),), DT)
    op = rocof_operator(t, breaks=(5.0,))
    derived = DerivedNoise(source, (1.0,), time=t, matrix=(0.2 * op.matrix).tocsr())
    rows = np.delete(np.arange(t.size), [10, 11, 100])
    w = TimedWhitener(model, t[rows], derived, rows)
    sigma = dense_covariance(model, t[rows], derived, rows)
    exact = linalg.solve_triangular(np.linalg.cholesky(sigma), np.eye(rows.size), lower=True)
    assert np.max(np.abs(w.W.toarray() - exact)) < 1e-9 * np.max(np.abs(exact))


@pytest.mark.parametrize("rows", [1, 2, 3, 6, 17, 39, 129, 1000])
def test_the_timed_whitening_gives_scipys_sparse_product_bit_for_bit(rows):
    """The band kernel (noise/band.c) in place of scipy's CSR product: the same numbers to
    the last bit, laid out the same, on a jittered recording with the derived ROCOF's
    noise (rows of W of every length up to a couple of hundred)."""
    from rapid_cosim.noise import band

    t = _jittered(n=600, drop=(40, 41, 42, 150))
    model = RecorderNoise(0.9e-3, ((1.2e-3, 0.6),), DT)
    derived = DerivedNoise(RecorderNoise(0.3e-3, ((0.9e-3, 0.15),), DT), (1.0,), time=t,
                           matrix=(0.2 * rocof_operator(t, breaks=(5.0,)).matrix).tocsr())
    keep = np.delete(np.arange(t.size), [10, 11, 100])
    w = TimedWhitener(model, t[keep], derived, keep)
    assert band.library() is not None, "the band kernel was not built or does not agree with scipy here"
    assert w._band is not None and np.diff(w.W.indptr).max() > 50
    r = np.random.default_rng(rows).standard_normal((rows, keep.size)) * 1e-3
    got, expected = w.whiten(r), np.asarray((w.W @ r.T).T)
    assert np.array_equal(got, expected)
    assert got.flags.f_contiguous == expected.flags.f_contiguous and got.flags.c_contiguous == expected.flags.c_contiguous
    if rows > 1:  # every way this processor has, not only the one it takes (band.ways())
        lib = band.library()
        for way in band._ways(lib):
            assert np.array_equal(w._band.rows_by(lib, way, r), expected), band.WAYS[way]


def test_a_matrix_that_is_not_a_band_is_left_to_scipy():
    from scipy import sparse

    from rapid_cosim.noise.band import Band, product

    gappy = sparse.csr_matrix(np.array([[1.0, 0.0, 0.0], [2.0, 0.0, 3.0], [0.0, 4.0, 5.0]]))
    assert Band.of(gappy) is None and Band.of(sparse.csr_matrix((3, 3))) is None
    assert Band.of(sparse.csr_matrix(np.ones((2, 3)))) is None
    r = np.arange(6.0).reshape(2, 3)
    assert np.array_equal(product(gappy, None, r), (gappy @ r.T).T)
    band = Band.of(sparse.csr_matrix(np.tril(np.ones((3, 3)))))
    assert band is not None and band.first.tolist() == [0, 0, 0]


def test_without_a_c_compiler_the_whitening_says_so_and_uses_scipys_product(monkeypatch, tmp_path):
    from rapid_cosim.noise import band

    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    monkeypatch.setenv("RAPID_COSIM_CACHE", str(tmp_path / "cache"))
    band.library.cache_clear()
    try:
        with pytest.warns(UserWarning, match="no-such-cc.*scipy's sparse product"):
            assert band.library() is None
        t = _jittered(n=200)
        w = TimedWhitener(RecorderNoise(0.9e-3, ((1.2e-3, 0.6),), DT), t)
        r = np.random.default_rng(0).standard_normal((3, t.size))
        assert np.array_equal(w.whiten(r), (w.W @ r.T).T)
    finally:
        band.library.cache_clear()


def test_a_band_product_that_differs_from_scipys_is_not_used(monkeypatch):
    from rapid_cosim.noise import band

    monkeypatch.setattr(band, "_agrees", lambda lib: False)
    band.library.cache_clear()
    try:
        with pytest.warns(UserWarning, match="does not give scipy's numbers"):
            assert band.library() is None
    finally:
        band.library.cache_clear()
    t = _jittered(n=200)
    w = TimedWhitener(RecorderNoise(0.9e-3, ((1.2e-3, 0.6),), DT), t)
    with pytest.raises(ValueError, match="dimension mismatch"):
        w._band.apply(np.zeros((2, t.size - 1)), band.library())


def test_on_regular_stamps_the_timed_whitening_is_the_stationary_ones():
    t = np.arange(400) * DT
    model = RecorderNoise(0.9e-3, ((1.2e-3, 0.6),), DT)
    e = np.random.default_rng(3).standard_normal((3, t.size))
    assert np.max(np.abs(TimedWhitener(model, t).whiten(e) - model.whitener().whiten_runs(e))) < 1e-8
    op = rocof_operator(t)
    taps = tuple(0.2 * np.asarray(op.matrix[200].data))
    source = RecorderNoise(0.3e-3, ((0.9e-3, 0.15),), DT)
    stationary = RecorderNoise(0.9e-3, ((1.2e-3, 0.6),), DT, (FilteredNoise(source, taps),))
    derived = DerivedNoise(source, taps, time=t, matrix=(0.2 * op.matrix).tocsr())
    exact = TimedWhitener(model, t, derived, np.arange(t.size)).whiten(e)
    levinson = LevinsonWhitener(stationary).whiten_runs(e)
    middle = slice(100, 300)  # away from the ends, where the filter is the same at every sample
    assert np.max(np.abs(exact[:, middle] - levinson[:, middle])) < 1e-6 * np.max(np.abs(levinson))


def test_the_whitening_takes_the_exact_path_where_the_stamps_ask_for_it():
    model = RecorderNoise(0.9e-3, ((1.2e-3, 0.6),), DT)
    assert not Whitening(model, np.arange(300) * DT).exact
    assert Whitening(model, _jittered(n=300)).exact
    assert Whitening(model, np.delete(np.arange(300) * DT, [50])).exact


def test_samples_of_the_derived_noise_have_its_covariance():
    t = _jittered(n=120, drop=(30,))
    source = RecorderNoise(0.3e-3, ((0.9e-3, 0.15),), DT)
    derived = DerivedNoise(source, (1.0,), time=t, matrix=rocof_operator(t).matrix.tocsr())
    rows = np.arange(10, 110)
    draws = derived.sample_rows(rows, np.random.default_rng(4), 20000)
    exact = dense_covariance(RecorderNoise(1e-12, (), DT), t[rows], derived, rows)
    assert np.allclose(np.cov(draws.T), exact, atol=0.05 * exact.max())


# --------------------------------------------------------------------------- an event, untidy


def _copy_event(tmp_path: Path) -> Path:
    folder = tmp_path / "event"
    shutil.copytree(EVENT, folder)
    return folder


def _edit_rows(folder: Path, edit) -> None:
    lines = (folder / "data.csv").read_text().splitlines()
    (folder / "data.csv").write_text("\n".join([lines[0]] + edit(lines[1:])) + "\n")


def test_a_pdc_recording_is_repaired_flagged_bridged_and_said(tmp_path):
    """Repeated frames, a burst of five dropped, frames flagged invalid by a STAT word and
    carrying zeros: each repaired or masked, and each said."""
    folder = _copy_event(tmp_path)

    def pdc(rows):
        out = []
        for k, row in enumerate(rows):
            if 700 <= k < 705:
                continue  # a burst of five dropped
            time, f, p = row.split(",")
            stat = 0x8000 if k in (300, 900, 1500) else 0
            if stat:
                f, p = "0.0", "0.0"
            out.append(f"{time},{f},{p},{stat}")
            if k in (400, 1200):
                out.append(out[-1])  # repeated
        return out

    _edit_rows(folder, pdc)
    text = (folder / "data.csv").read_text().replace("time,FREQ,P", "time,FREQ,P,STAT")
    (folder / "data.csv").write_text(text)
    config = folder / "config.toml"
    config.write_text(config.read_text().replace('outputs =', 'flags = { column = "STAT" }\noutputs ='))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        exp = load_experiment(config)
    said = " ".join(str(w.message) for w in caught)
    assert "2 repeated stamp(s) dropped" in said and "3 frame(s), every column, masked" in said
    lines = exp.recording.lines()
    assert "5 frame(s) missing, at most 5 in a row" in lines[0] and "2 repeated stamp(s) dropped" in lines[0]
    assert any("STAT word 'STAT' marks the frame invalid" in line and "rows 302, 898, 1499" in line for line in lines)
    assert any(line.startswith("input 'FREQ': 4 hole(s) bridged") for line in lines)
    assert exp.data.n_valid("P") == len(exp.data) - 3
    assert np.all(np.isfinite(exp.input_table.values))
    assert exp.recording.to_json()["timebase"]["data.csv"]["repeated"] == 2


def test_values_no_recorder_can_mean_are_masked_and_named(tmp_path):
    """Zeros without a STAT word: the frequency is outside 60 +- 5 Hz, the power a spike of
    a whole rating out and back within a frame."""
    folder = _copy_event(tmp_path)

    def zeros(rows):
        for k in (500, 1000):
            time = rows[k].split(",")[0]
            rows[k] = f"{time},0.0,0.0"
        return rows

    _edit_rows(folder, zeros)
    with pytest.warns(Warning) as caught:
        exp = load_experiment(folder / "config.toml")
    said = " ".join(str(w.message) for w in caught)
    assert "2 sample(s) of 'FREQ' masked: outside 60 +- 5 Hz (rows 502, 1002)" in said
    assert "2 sample(s) of 'P' masked: a one- or two-frame spike" in said
    assert exp.data.n_valid("FREQ") == exp.data.n_valid("P") == len(exp.data) - 2
    config = folder / "config.toml"
    config.write_text(config.read_text().replace('outputs =', 'limits = { power_step = false }\noutputs ='))
    with pytest.warns(Warning) as caught:
        exp = load_experiment(config)
    assert exp.data.n_valid("P") == len(exp.data)


@pytest.mark.parametrize("case, message", [
    ("backwards", r"data.csv, row 12: column 'time': time goes back from 0.3 s \(row 11\) to 0.2 s \(row 12\), 3 frames"),
    ("duplicate", r"data.csv, row 12: column 'P': time 0.3 s is written twice \(rows 11 and 12\) with different"),
    ("stat_type", r"\[data.flags.column\].*column 'STAT' is not a C37.118 STAT word .* at rows 7: 0.5"),
    ("all_invalid", r"\[data.flags.column\].*column 'STAT' marks every sample invalid"),
    ("milliseconds", r"\[data.time\].*steps by 33.3\d* per sample.*time_unit = \"ms\""),
    ("long_gap", r"\[inputs.f_dev\]: column 'FREQ' has no valid sample between 19.9667 s and 21 s \(1 s\).*"
                 r"add gaps = \{ max = 1, fill = \"linear\" \}"),
])
def test_bad_recordings_are_named_by_file_column_and_rows(tmp_path, case, message):
    folder = _copy_event(tmp_path)
    config = folder / "config.toml"

    def edit(rows):
        if case == "backwards":
            rows[10] = "0.2000" + rows[10][6:]
        elif case == "duplicate":
            rows[10] = rows[9].rsplit(",", 1)[0] + ",999.0"
        elif case == "long_gap":
            rows[600:630] = [r.split(",")[0] + ",," + r.split(",")[2] for r in rows[600:630]]
        elif case == "milliseconds":
            rows = [f"{1000 * float(r.split(',')[0]):.1f}," + r.split(",", 1)[1] for r in rows]
        elif case in ("stat_type", "all_invalid"):
            rows = [r + (",0.5" if k == 5 and case == "stat_type" else ",0" if case == "stat_type" else ",49152")
                    for k, r in enumerate(rows)]
        return rows

    _edit_rows(folder, edit)
    if case in ("stat_type", "all_invalid"):
        (folder / "data.csv").write_text((folder / "data.csv").read_text().replace("time,FREQ,P", "time,FREQ,P,STAT"))
        config.write_text(config.read_text().replace('outputs =', 'flags = { column = "STAT" }\noutputs ='))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises((ConfigError, DataError), match=message):
            load_experiment(config)
    if case == "milliseconds":
        config.write_text(config.read_text().replace('time = "time"', 'time = "time"\ntime_unit = "ms"'))
        assert load_experiment(config).data.time[-1] == pytest.approx(60.0)


def test_every_repair_is_said_by_the_cli_the_archive_json_and_the_report(tmp_path, capsys):
    """A PDC-like recording calibrated: the CLI's estimate prints each repair, ``show
    --json`` carries them, the run re-runs bit for bit from its archive alone (the masks
    re-made from the config and the stamps' repairs kept), and the validation page says
    them in its recordings section."""
    from rapid_cosim.cli import main
    from rapid_cosim.report.html import validation_page

    folder = _copy_event(tmp_path)

    def untidy(rows):
        out = []
        for k, row in enumerate(rows):
            if 700 <= k < 702:
                continue
            time, f, p = row.split(",")
            out.append(f"{time},{f},{p},{0xC000 if k == 900 else 0}")
            if k == 400:
                out.append(out[-1])
        return out

    _edit_rows(folder, untidy)
    (folder / "data.csv").write_text((folder / "data.csv").read_text().replace("time,FREQ,P", "time,FREQ,P,STAT"))
    config = folder / "config.toml"
    config.write_text(config.read_text().replace('outputs =', 'flags = { column = "STAT" }\noutputs ='))
    archive = tmp_path / "run.h5"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["estimate", str(config), "--method", "nm", "--option", "nm.max_fev=30", "--archive",
                     str(archive), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "tgov1_on: time base of data.csv: 1799 samples" in printed
    assert "2 frame(s) missing" in printed and "1 repeated stamp(s) dropped" in printed
    assert "1 frame(s), every column, masked: the C37.118 STAT word 'STAT'" in printed
    json_file = tmp_path / "show.json"
    assert main(["show", str(archive), "--json", str(json_file)]) == 0
    import json

    recording = json.loads(json_file.read_text())["recordings"]["tgov1_on"]
    assert recording["timebase"]["data.csv"]["repeated"] == 1 and recording["masked"][0]["count"] == 1
    import rapid_cosim as rc

    assert rc.rerun(archive).identical
    validation_page(archive, tmp_path / "page.html", pdf=False)
    html = (tmp_path / "page.html").read_text()
    assert "id=timebase" in html and "1 repeated stamp(s) dropped" in html and "STAT word" in html


def test_a_triangular_map_gives_each_row_the_same_sums_alone_and_in_a_batch(monkeypatch):
    """The stationary whiteners' first samples (noise.band.Triangular): a run of any
    length n <= m against BLAS's product to rounding, one row and many bit for bit, and
    scipy's product (no C compiler) the same numbers as the kernel."""
    from rapid_cosim.noise import band

    rng = np.random.default_rng(5)
    W = np.tril(rng.standard_normal((40, 40)))
    T = band.Triangular(W)
    for n in (1, 2, 17, 39, 40):
        y = rng.standard_normal((9, n))
        out = T.apply(y)
        assert out.shape == (9, n) and out.flags.c_contiguous
        assert np.allclose(out, y @ W[:n, :n].T, rtol=0, atol=1e-13)
        assert np.array_equal(np.vstack([T.apply(y[k:k + 1]) for k in range(9)]), out)
        monkeypatch.setattr(band, "library", lambda: None)
        assert np.array_equal(T.apply(y), out)
        monkeypatch.undo()
    assert T.apply(np.zeros((3, 0))).shape == (3, 0)


def test_regular_stamps_are_called_regular_and_a_noted_recording_not_jittered():
    """Issue 56: a 0.1 s base summed in floating point (jitter 1e-11 ms) was described as
    'jittered stamps'. Regular stamps are called regular; a recording whose only fact is
    a note (a units row skipped) is told by its lines, not lumped with the jittered."""
    from rapid_cosim.data.timebase import inspect
    from rapid_cosim.experiment.recording import Recording
    from rapid_cosim.identify.result import recording_story

    time = np.cumsum(np.full(900, 0.1)) - 0.1  # 0.1 summed: off the grid by rounding only
    base = inspect(time, "a.csv")
    assert base.regular and "regular stamps" in base.describe() and "jitter" not in base.describe()
    jittered = inspect(time + np.random.default_rng(1).uniform(-0.003, 0.003, time.size), "b.csv")
    assert not jittered.regular and "jitter" in jittered.describe()
    noted = Recording({"a.csv": base}, notes=("a units row under the header skipped",)).summary()
    story = recording_story({"t1": noted, "t2": Recording({"b.csv": jittered}).summary()})
    assert any(line.startswith("recording t1: ") and "units row" in line for line in story), story
    assert any(line.startswith("recordings: t2 with jittered stamps") for line in story), story
    assert not any("t1" in line and "jittered" in line for line in story), story
