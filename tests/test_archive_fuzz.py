"""Damaged archives: every command ends in a correct result or one clear line, never a
traceback or a hang (see tests/archive_fuzz.py). The CI suite runs 60 corruptions; the
slow suite 500."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from archive_fuzz import expected_of, fuzz
from conftest import slow_objective

from rapid_cosim.archive import RunArchive
from rapid_cosim.calibration import RunOptions, inputs_from_configs, start_run
from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment

FIXED = {"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 2.0}
ESTIMATE = {"gov.R": {"min": 0.02, "max": 0.12}, "gov.Ts": {"min": 0.1, "max": 20.0}}
OPTIONS = dict(method="pso:4+nm", seed=3, estimator_options={"pso": {"n_particles": 8}, "nm": {"max_iter": 15}})

WRITER = slow_objective(0.05) + """
import sys
from rapid_cosim.calibration import RunOptions, inputs_from_configs, start_run
start_run(inputs_from_configs([sys.argv[1]]), RunOptions(**{options!r}), sys.argv[2], progress=False)
"""


@pytest.fixture(scope="module")
def archives(fmus, tmp_path_factory, repo):
    """A finished archive and one of the same run killed half-way (status 'running')."""
    folder = tmp_path_factory.mktemp("fuzz")
    t, y = synthesize(fmus["StagedTest"], {**FIXED, "gov.R": 0.06, "gov.Ts": 3.0}, duration=12.0,
                      noise=NoiseModel(white_sigma=0.0008), rng=np.random.default_rng(1))
    config = write_experiment(folder / "test1", model="iGrGen.TestBenches.StagedTest", time=t, values=y,
                              fixed=FIXED, estimate=ESTIMATE)
    finished = folder / "finished.h5"
    result = start_run(inputs_from_configs([config]), RunOptions(**OPTIONS), finished, progress=False)
    running = folder / "running.h5"
    proc = subprocess.Popen([sys.executable, "-c", WRITER.format(options=OPTIONS), str(config), str(running)],
                            cwd=repo)
    deadline = time.time() + 60
    while time.time() < deadline:
        time.sleep(0.05)
        try:
            with RunArchive(running) as view:
                if view.n_iterations >= 3:
                    break
        except Exception:
            pass
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    (folder / "running.h5.lock").unlink(missing_ok=True)
    with RunArchive(running) as view:
        assert view.status == "running" and 3 <= view.n_iterations < result.nit
    paths = {"finished": finished, "running": running}
    return paths, {label: expected_of(p, result) for label, p in paths.items()}


def _check(tally, n):
    print(f"\n{n} corruptions x 5 commands: " + ", ".join(f"{k} {tally[k]}" for k in
                                                           ("correct", "error", "traceback", "hang", "silent")))
    assert tally["correct"] + tally["error"] == 5 * n
    assert tally["traceback"] == tally["hang"] == tally["silent"] == 0


def test_damaged_archives_give_a_correct_result_or_one_clear_line(archives, tmp_path, capsys):
    paths, expected = archives
    tally = fuzz(paths, expected, 60, tmp_path, seed=1, log=print)
    with capsys.disabled():
        _check(tally, 60)


@pytest.mark.slow
def test_five_hundred_damaged_archives(archives, tmp_path, capsys):
    paths, expected = archives
    tally = fuzz(paths, expected, 500, tmp_path, seed=2, log=print)
    with capsys.disabled():
        _check(tally, 500)
