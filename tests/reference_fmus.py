"""The FMI standard's own Reference FMUs (the Modelica Association's, BSD-2-Clause), built
from ``../shared/reference-fmus`` with CMake, and what each is compared with: fmpy (Model
Exchange with its CVode at rtol 1e-10, Co-Simulation at the same communication step) and
closed forms where there are.

They check the FMI state machines strictly (an illegal call is logged and refused) and
bring what the project's own test FMUs do not: every FMI 3.0 type, inputs of every type,
arrays sized by structural parameters, a resource file, a model that asks to stop, a stiff
one, clocks. :func:`build` runs CMake once per FMI version and source and keeps the FMUs
in the cache (``$RAPID_COSIM_CACHE``, which the test session sets afresh: built once per
test run; the benchmark reuses the user's cache). :func:`unavailable` says why they cannot
be built: a user's clone has no ``../shared``, a machine may have no cmake.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SOURCE = Path(os.environ.get("RAPID_COSIM_REFERENCE_FMUS", REPO.parent / "shared" / "reference-fmus"))
MODELS = {"2.0": ("BouncingBall", "Dahlquist", "Feedthrough", "Resource", "Stair", "VanDerPol"),
          "3.0": ("BouncingBall", "Clocks", "Dahlquist", "Feedthrough", "Resource", "Roberts", "Stair",
                  "StateSpace", "VanDerPol")}
ME, CS = "ModelExchange", "CoSimulation"
# What is refused, and the FMI feature its message names.
REFUSED = {("3.0", "Clocks"): "Scheduled Execution"}
# (start, stop, output interval = communication step) per model; Roberts' Co-Simulation
# takes the FMU's own Euler at 1 microsecond, so 10 ms of it.
EXPERIMENTS = {"BouncingBall": (0.0, 3.0, 0.01), "Dahlquist": (0.0, 10.0, 0.1), "Feedthrough": (0.0, 2.0, 0.1),
               "Resource": (0.0, 1.0, 0.1), "Stair": (0.0, 10.0, 0.2), "VanDerPol": (0.0, 20.0, 0.1),
               "StateSpace": (0.0, 10.0, 0.1), "Roberts": (1e-5, 40.0, 0.4)}
ROBERTS_CS = (1e-5, 0.01, 1e-3)
RTOL = 1e-10  # Model Exchange, fmpy's and ours


def cases() -> list[tuple[str, str, str]]:
    """(version, model, interface) of every run fmpy makes of the two builds."""
    return [(v, m, i) for v in MODELS for m in MODELS[v] if (v, m) not in REFUSED for i in (ME, CS)]


def experiment(model: str, interface: str) -> tuple[float, float, float]:
    return ROBERTS_CS if (model, interface) == ("Roberts", CS) else EXPERIMENTS[model]


def grid(model: str, interface: str) -> np.ndarray:
    """The output times, start + k * step as fmpy makes its communication points."""
    start, stop, step = experiment(model, interface)
    return start + step * np.arange(round((stop - start) / step) + 1)


def cmake() -> str | None:
    """The system's cmake, else the one pip installs beside fmpy (fmpy requires it)."""
    beside = Path(sys.executable).parent / "cmake"
    return shutil.which("cmake") or (str(beside) if beside.is_file() else None)


def unavailable() -> str | None:
    """Why the Reference FMUs cannot be built here, or None."""
    if not (SOURCE / "CMakeLists.txt").is_file():
        return f"the Reference FMUs' source is absent ({SOURCE}; a clone without ../shared)"
    if cmake() is None:
        return "cmake is not installed (it builds the Reference FMUs)"
    missing = [tool for tool, names in (("make", ["make"]), ("a C compiler", [os.environ.get("CC", "cc")]),
                                        ("a C++ compiler (CMake's project() asks for one)", ["c++", "g++", "clang++"]))
               if not any(shutil.which(n) for n in names)]
    return f"{', '.join(missing)} not found (CMake builds the Reference FMUs with them)" if missing else None


def _source_key(version: str) -> str:
    digest = hashlib.sha256(f"{version}|{os.environ.get('CC', 'cc')}".encode())
    for path in sorted(SOURCE.rglob("*")):
        parts = path.relative_to(SOURCE).parts
        if path.is_file() and parts[0] not in (".git", "tests", "playground", ".github"):
            digest.update("/".join(parts).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def build(version: str) -> dict[str, Path]:
    """Model name -> FMU of one FMI version ("2.0" or "3.0"), built once per source and
    kept in the cache; CMake builds the models' targets only, on two jobs."""
    from rapid_cosim.compiler.embedded import cache_dir

    folder = cache_dir() / f"reference-fmus-{version[0]}-{_source_key(version)}"
    fmus = {m: folder / f"{m}.fmu" for m in MODELS[version]}
    if all(f.is_file() for f in fmus.values()):
        return fmus
    folder.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="reference-fmus-", dir=folder.parent) as tmp:
        work = Path(tmp) / "build"
        for cmd in ([cmake(), "-S", str(SOURCE), "-B", str(work), f"-DFMI_VERSION={version[0]}"],  # as published
                    [cmake(), "--build", str(work), "-j", "2", "--target", *MODELS[version]]):
            proc = subprocess.run(cmd, capture_output=True, text=True)
            if proc.returncode != 0:
                raise RuntimeError(f"building the Reference FMUs failed: {' '.join(cmd)}\n{proc.stdout[-3000:]}"
                                   f"\n{proc.stderr[-3000:]}")
        done = Path(tmp) / "fmus"
        done.mkdir()
        for model in MODELS[version]:
            shutil.copy(work / "fmus" / f"{model}.fmu", done / f"{model}.fmu")
        try:
            os.replace(done, folder)  # whole or not at all: a concurrent build may have won
        except OSError:
            if not all(f.is_file() for f in fmus.values()):
                raise
    return fmus


# --------------------------------------------------------------------------- runs


def fmpy_run(path: Path, model: str, interface: str, **kw) -> np.ndarray:
    """fmpy's simulate_fmu on the case's grid: Model Exchange with CVode at RTOL,
    Co-Simulation with the output interval as its communication step."""
    import fmpy

    start, stop, step = experiment(model, interface)
    if interface == ME:
        kw.setdefault("relative_tolerance", RTOL)
    return fmpy.simulate_fmu(str(path), fmi_type=interface, start_time=start, stop_time=stop, output_interval=step,
                             **kw)


def ours(sim, model: str, interface: str, runner: str | None = None, **kw):
    """A Simulator's run of the case (its relative tolerance is the Simulator's)."""
    start, _, step = experiment(model, interface)
    if interface == CS:
        kw.setdefault("communication_step", step)
    return sim.simulate({}, output_times=grid(model, interface), start_time=start, runner=runner, **kw)


def column(ref: np.ndarray, name: str) -> np.ndarray:
    """fmpy's column of one of our outputs ("y[2]": the array y's second element)."""
    if name in ref.dtype.names:
        return ref[name].astype(float)
    base, index = name[:-1].split("[")
    return ref[base][:, int(index) - 1].astype(float)


def on_grid(ref: np.ndarray, times: np.ndarray, names) -> dict[str, np.ndarray]:
    """fmpy's values at our output times: the last row written at each (fmpy writes an
    event's time twice, before and after it; ours are the values after it). NaN where
    fmpy wrote no row."""
    rows = np.full(times.size, -1)
    for k, t in enumerate(times):
        match = np.flatnonzero(np.isclose(ref["time"], t, rtol=0.0, atol=1e-9 * max(1.0, abs(t))))
        rows[k] = match[-1] if match.size else -1
    out = {}
    for n in names:
        values = column(ref, n)
        out[n] = np.where(rows >= 0, values[np.maximum(rows, 0)], np.nan)
    return out


def largest_difference(traj, ref: np.ndarray, until: float = np.inf) -> float:
    """The largest |ours - fmpy| over outputs and the output times before ``until``."""
    keep = traj.time < until
    theirs = on_grid(ref, traj.time[keep], traj.outputs)
    worst = 0.0
    for n, values in theirs.items():
        both = np.isfinite(values)
        assert both.any(), f"fmpy wrote no row at our times for {n}"
        worst = max(worst, float(np.max(np.abs(traj[n][keep][both] - values[both]))))
    return worst


def closed_form(model: str, times: np.ndarray) -> dict[str, np.ndarray] | None:
    """Exact solutions: Dahlquist x' = -k x (k = 1), x = exp(-t); StateSpace (A, B, C, D
    identities, x(0) = 0, u = 1 2 3 held) y = u exp(t)."""
    if model == "Dahlquist":
        return {"x": np.exp(-times)}
    if model == "StateSpace":
        return {f"y[{i}]": i * np.exp(times) for i in (1, 2, 3)}
    return None


def first_impact() -> float:
    """BouncingBall (h0 = 1 m, g = -9.81 m/s^2) first reaches the floor at sqrt(2 h0 / g)."""
    return float(np.sqrt(2.0 / 9.81))


# Where fmpy and rapid-cosim record differently, by design: Stair asks to terminate at the
# event at t = 9 s; fmpy's Model Exchange run writes the value before that event and stops,
# ours (as fmpy's Co-Simulation run) the value after it. Compared before that time.
COMPARED_UNTIL = {("Stair", ME): 9.0}
