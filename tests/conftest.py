"""Shared fixtures: the repository's paths and its test-bench FMUs (built once, then
only when the Modelica sources change)."""

from __future__ import annotations

import os
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
