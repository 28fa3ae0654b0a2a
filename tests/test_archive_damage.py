"""Damage a user meets: ``verify`` names the damaged part, ``show`` shows what is intact,
``resume`` continues from the last intact iteration, and archives written before
checksums existed (format 1) still show and re-run."""

import json

import h5py
import numpy as np
import pytest

from rapid_cosim.archive import RunArchive
from rapid_cosim.archive import seal
from rapid_cosim.archive.verify import verify
from rapid_cosim.calibration import RunOptions, inputs_from_configs, rerun, resume_run, start_run
from rapid_cosim.cli import main
from rapid_cosim.errors import ArchiveDamaged
from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment

FIXED = {"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 3.0}
ESTIMATE = {"gov.R": {"min": 0.02, "max": 0.12}, "gov.Ts": {"min": 0.1, "max": 20.0}}
OPTIONS = dict(method="pf:6+nm", seed=9, estimator_options={"pf": {"n_particles": 12}})


@pytest.fixture(scope="module")
def config(fmus, tmp_path_factory):
    t, y = synthesize(fmus["StagedTest"], {**FIXED, "gov.R": 0.05, "gov.Ts": 2.0}, duration=15.0,
                      noise=NoiseModel(white_sigma=0.0008), rng=np.random.default_rng(2))
    return write_experiment(tmp_path_factory.mktemp("damage") / "syn", model="iGrGen.TestBenches.StagedTest",
                            time=t, values=y, fixed=FIXED, estimate=ESTIMATE)


@pytest.fixture(scope="module")
def finished(config, tmp_path_factory):
    path = tmp_path_factory.mktemp("finished") / "run.h5"
    return path, start_run(inputs_from_configs([config]), RunOptions(**OPTIONS), path, progress=False)


def _damage_iteration(path, k):
    """Flip a bit in the stored fitness of iteration ``k`` (inside the bytes a live writer
    may change, so the seal does not see it: the iteration's own checksum must)."""
    with RunArchive(path) as view:
        row = view.iterations()[k]
    with h5py.File(path, "r", locking=False) as f:
        ds = f["evaluations/fitness"]
        offset = ds.id.get_offset() + 8 * (int(np.flatnonzero(f["evaluations/iteration"][()] == k)[0]))
    with open(path, "r+b") as fh:
        fh.seek(offset)
        byte = fh.read(1)
        fh.seek(offset)
        fh.write(bytes([byte[0] ^ 0x10]))
    return row


def test_verify_names_the_damaged_iteration_and_what_is_intact(finished, tmp_path, capsys):
    path, _ = finished
    damaged = tmp_path / "run.h5"
    damaged.write_bytes(path.read_bytes())
    _damage_iteration(damaged, 4)
    checks = {c.part: c for c in verify(damaged)}
    assert checks["iteration 4"].intact is False and "iterations 0 to 3 intact" in checks["iteration 4"].detail
    assert all(c.intact for part, c in checks.items() if part != "iteration 4")
    assert main(["verify", str(damaged)]) == 1
    assert main(["verify", str(path)]) == 0
    out = capsys.readouterr().out
    assert "DAMAGED iteration 4" in out and f"{path}: intact" in out


def test_show_shows_what_is_intact_of_a_damaged_archive(finished, tmp_path, capsys):
    path, _ = finished
    damaged = tmp_path / "run.h5"
    damaged.write_bytes(path.read_bytes())
    _damage_iteration(damaged, 4)
    assert main(["show", str(damaged), "--json", str(tmp_path / "s.json")]) == 2
    captured = capsys.readouterr()
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["nit"] == 4 and summary["experiments"] == ["syn"]  # the intact iterations, the inputs
    assert "damaged iteration 4 (checksum mismatch)" in captured.err and "Traceback" not in captured.err


def test_resume_continues_from_the_last_intact_iteration(config, finished, tmp_path):
    _, expected = finished
    path = tmp_path / "run.h5"
    with pytest.raises(KeyboardInterrupt):  # a run stopped after 8 iterations
        inputs = inputs_from_configs([config])
        from rapid_cosim.calibration import runs

        real = runs._execute

        def stopping(inputs, options, objective, on_iteration, progress):
            def counted(it):
                on_iteration(it)
                if it.index == 7:
                    raise KeyboardInterrupt
            return real(inputs, options, objective, counted, progress)

        runs._execute = stopping
        try:
            start_run(inputs, RunOptions(**OPTIONS), path, progress=False)
        except Exception as e:  # RunInterrupted, as the command line shows it
            raise KeyboardInterrupt from e
        finally:
            runs._execute = real
    with RunArchive(path) as view:
        assert view.status == "interrupted" and view.n_iterations == 8
    _damage_iteration(path, 5)
    with pytest.warns(UserWarning, match="iteration 5 onwards is damaged"):
        resumed = resume_run(path, progress=False)
    assert np.array_equal(resumed.x, expected.x) and resumed.fun == expected.fun and resumed.nfev == expected.nfev
    assert all(c.intact for c in verify(path))


def test_a_damaged_structure_never_reaches_hdf5(finished, tmp_path):
    path, _ = finished
    damaged = tmp_path / "run.h5"
    data = bytearray(path.read_bytes())
    data[seal.USERBLOCK + 200] ^= 0xFF  # inside HDF5's own structure, where a bad byte can hang it
    damaged.write_bytes(bytes(data))
    with pytest.raises(ArchiveDamaged, match="damaged HDF5 structure"):
        RunArchive(damaged)


def _as_format_1(path):
    """An archive as the writer of format 1 left it: no seal, no checksums."""
    with h5py.File(path, "r", locking=False) as src, h5py.File(path.with_suffix(".v1.h5"), "w",
                                                                  libver=("earliest", "v108"), track_order=True) as dst:
        for name, obj in src.items():
            if name not in ("committed", "iterations"):
                src.copy(obj, dst, name)
        dst.attrs.update({k: v for k, v in src.attrs.items() if k != "crc32"})
        dst.attrs["format_version"] = 1
        dst["committed"] = src["committed"][()][:2]
        it = dst.create_group("iterations")
        table = src["iterations/table"][()]
        names = [n for n in table.dtype.names if n != "crc"]
        it["table"] = np.array(table[names].tolist(), dtype=[(n, table.dtype[n]) for n in names])
        for blob in ("rng_state", "extras"):
            it[blob] = src["iterations"][blob][()]

        def strip(name, obj):
            if "crc32" in obj.attrs:
                del obj.attrs["crc32"]

        dst.visititems(strip)
    return path.with_suffix(".v1.h5")


def test_an_archive_of_format_1_still_shows_and_reruns(finished, tmp_path, capsys):
    path, expected = finished
    copy = tmp_path / "run.h5"
    copy.write_bytes(path.read_bytes())
    old = _as_format_1(copy)
    with RunArchive(old) as view:
        assert view.format_version == 1 and not view.checksums and view.result().fun == expected.fun
    assert main(["show", str(old)]) == 0
    report = rerun(old, progress=False)
    assert report.identical, report.first_difference
    assert any(c.part == "HDF5 structure" and "format 1" in c.detail for c in verify(old))
