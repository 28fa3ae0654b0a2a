"""Shared fixtures: the repository's paths and its test-bench FMUs (built once, then
only when the Modelica sources change)."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).parent))  # the reference models are a test helper
# A cache of built FMUs and of the runner library of the session's own, so that no test
# depends on what earlier runs left in the user's cache (workers and CLI subprocesses
# inherit it).
os.environ["RAPID_COSIM_CACHE"] = tempfile.mkdtemp(prefix="rapid_cosim_test_cache_")


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def fmus(repo) -> dict[str, Path]:
    """Short bench name -> FMU path, e.g. fmus['StagedTest']."""
    from rapid_cosim.compiler import build_models

    outcomes = build_models(package=repo / "modelica" / "iGrGen", fmu_dir=repo / "fmus", log=lambda *_: None)
    return {o.model.rsplit(".", 1)[-1]: o.fmu for o in outcomes}


@pytest.fixture(scope="session")
def study(repo, tmp_path_factory):
    """(work folder, package copy, FMU folder) with the base bench and every catalogue
    effect's bench built: what the synthetic diagnosis studies run on."""
    from rapid_cosim.compiler import build_models
    from rapid_cosim.diagnose.catalogue import BASE_BENCH, EFFECTS

    work = tmp_path_factory.mktemp("study")
    package = work / "package" / "iGrGen"
    shutil.copytree(repo / "modelica" / "iGrGen", package)
    fmu_dir = work / "fmus"
    build_models(list(dict.fromkeys([BASE_BENCH, *(e.bench for e in EFFECTS.values())])), package=package,
                 fmu_dir=fmu_dir, log=lambda *_: None)
    return work, package, fmu_dir


# Python source that slows every objective call of the process it runs in by ``delay``
# seconds, so that a run in a subprocess lasts long enough to be interrupted or killed in
# the middle on any machine, however loaded; the results are those of an unslowed run.
def slow_objective(delay: float) -> str:
    return (f"import time\nfrom rapid_cosim.fitting.objective import ProblemObjective\n_call = ProblemObjective.__call__\n"
            f"ProblemObjective.__call__ = lambda self, X: (time.sleep({delay!r}), _call(self, X))[1]\n")


def gated_objective(gate, open_calls: int) -> str:
    """Code that holds ProblemObjective at its call ``open_calls + 1`` while the file
    ``gate`` exists (300 s at most): a run in a subprocess then stays in the middle until
    the test has done what it waits to do (send a signal, read the live archive), however
    loaded the machine. A fixed delay per call raced: on a busy machine the archive was
    first read once the run had finished, and the signal met an exit with status 0. On
    reaching the gate the run writes ``gate.held``: a signal sent before that can land
    inside a simulation's callback, where Python drops it (ctypes ignores an exception
    raised in a callback), and the run then waits at the gate for good."""
    return (f"import os, time\nfrom rapid_cosim.fitting.objective import ProblemObjective\n"
            f"_call, _n = ProblemObjective.__call__, [0]\n"
            f"def _gated(self, X):\n"
            f"    _n[0] += 1\n"
            f"    if _n[0] == {open_calls + 1}:\n"
            f"        open({str(gate) + '.held'!r}, 'w').close()  # held from here on: the test may act\n"
            f"    deadline = time.time() + 300\n"
            f"    while _n[0] > {open_calls} and os.path.exists({str(gate)!r}) and time.time() < deadline:\n"
            f"        time.sleep(0.02)\n"
            f"    return _call(self, X)\n"
            f"ProblemObjective.__call__ = _gated\n")


# A quick synthetic staged test (R 0.06, Ts 4 s, 25 s) for the run, fault and cluster tests.
SYNTH_FIXED = {"gov.p_ref": 0.6, "src.df": -0.2, "src.t_step": 5.0}
SYNTH_ESTIMATE = {"gov.R": {"min": 0.02, "max": 0.12, "label": "R"},
                  "gov.Ts": {"min": 0.1, "max": 20.0, "label": "Ts"}}


def synthetic_config(fmu, folder: Path, seed: int, duration: float = 25.0) -> Path:
    import numpy as np

    from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment

    t, y = synthesize(fmu, {**SYNTH_FIXED, "gov.R": 0.06, "gov.Ts": 4.0}, duration=duration,
                      noise=NoiseModel(white_sigma=0.0008, offset=0.001), rng=np.random.default_rng(seed))
    return write_experiment(folder, model="iGrGen.TestBenches.StagedTest", time=t, values=y, fixed=SYNTH_FIXED,
                            estimate=SYNTH_ESTIMATE)


BLOWUP = """package Bad
  model Blowup "x' = a x^2 reaches infinity at t = 1/a"
    parameter Real a(min = 0, max = 10) = 1;
    Real x(start = 1, fixed = true);
    output Real pm = x;
  equation
    der(x) = a * x ^ 2;
  end Blowup;
end Bad;
"""


@pytest.fixture(scope="session")
def blowup_fmu(tmp_path_factory) -> Path:
    """A model whose solution blows up at t = 1/a: a solver failure on demand."""
    from rapid_cosim.compiler import build_models

    root = tmp_path_factory.mktemp("bad")
    (root / "Bad.mo").write_text(BLOWUP)
    return build_models(["Bad.Blowup"], package=root / "Bad.mo", fmu_dir=root / "fmus", compiler="embedded",
                        log=lambda *_: None)[0].fmu


@pytest.fixture
def blowup(blowup_fmu):
    from rapid_cosim.simulator import Simulator

    return Simulator(blowup_fmu)
