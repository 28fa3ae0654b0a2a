"""Whole identifications under each way of the whitener's band product (issue 42): the
processor's own choice, then every other way it has forced in its place (AVX2, the pairs
of lanes every processor takes), each unit in one process, fresh folders. Every run
archive (each iteration as a resume compares it, with its extras, and each result) and
the delivered ``.dyr`` must be the same bit for bit: the band kernel's ways give the same
numbers end to end. Only the band kernel's way is forced: numpy's and the BLAS's own
dispatch are left to choose as they do on this processor.

    python benchmarks/ways_identify.py [--units electrical,steam] [--work /tmp/ways]
"""

from __future__ import annotations

import argparse
import filecmp
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
UNITS = {"electrical": ROOT / "experiments" / "electrical" / "unit.toml",
         "steam": ROOT / "experiments" / "steam" / "unit.toml"}

_ONE = """
import functools, sys, warnings
from pathlib import Path
warnings.simplefilter("ignore")
import rapid_cosim as rc
from rapid_cosim.noise import band
way = int(sys.argv[3])
lib = band.library()
if lib is None:
    sys.exit("the band kernel is not used on this machine")
if way:
    if not lib.rc_band_ways() & way:
        sys.exit(f"this processor has no way {way}")
    lib.rc_band_rows = functools.partial(lib.rc_band_rows_by, way)
rc.identify(Path(sys.argv[1]), workdir=Path(sys.argv[2]), engine=rc.EngineSpec(n_jobs=1), report=False,
            log=lambda *a: None)
"""


def identify_by(unit: Path, folder: Path, way: int) -> float:
    """Seconds to identify ``unit`` into ``folder`` (which must not exist) with the
    several-row product taken by ``way`` (0: the processor's own choice)."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", _ONE, str(unit), str(folder), str(way)], check=True, cwd=ROOT)
    return time.perf_counter() - t0


def differences(a: Path, b: Path) -> tuple[int, list[str]]:
    """The number of run archives under ``a`` and ``b``, and how those differ: every
    iteration compared as a resume compares it (:func:`~rapid_cosim.calibration.replay.same_iteration`)
    and with its extras (a multistart's waterfall), then the result (point, fitness,
    simulations, stop reason). An archive in one folder only, or unreadable in either, is
    a difference too."""
    from rapid_cosim.archive.reader import RunArchive
    from rapid_cosim.errors import ArchiveError

    names = {p.relative_to(a) for p in a.rglob("*.h5")} | {p.relative_to(b) for p in b.rglob("*.h5")}
    runs, differ = 0, []
    for name in sorted(names):
        if name.name == "diagnosis.h5":
            continue  # a diagnosis record, not a run (it names its own folder and times)
        runs += 1
        if not (a / name).exists() or not (b / name).exists():
            differ.append(f"{name} (in one folder only)")
            continue
        try:
            with RunArchive(a / name) as x, RunArchive(b / name) as y:
                why = _why(x.iterations(), y.iterations(), x.result(), y.result())
        except ArchiveError as e:
            why = f"unreadable: {str(e).splitlines()[0]}"
        if why:
            differ.append(f"{name} ({why})")
    return runs, differ


def _why(xs, ys, rx, ry) -> str | None:
    """Why two runs' iterations and results differ, or None where they do not."""
    from rapid_cosim.calibration.replay import same_iteration

    if len(xs) != len(ys):
        return f"{len(xs)} and {len(ys)} iterations"
    for i, j in zip(xs, ys):
        why = same_iteration(i, j)
        extras_i, extras_j = i.extras or {}, j.extras or {}
        if why is None and (extras_i.keys() != extras_j.keys()
                            or not all(np.array_equal(extras_i[k], extras_j[k]) for k in extras_i)):
            why = "extras"
        if why:
            return f"iteration {i.index}: {why}"
    if (rx is None) != (ry is None):
        return "one finished"
    if rx is not None and not (np.array_equal(rx.x, ry.x) and rx.fun == ry.fun and rx.nfev == ry.nfev
                               and rx.stop_reason == ry.stop_reason):
        return "result"
    return None


def same_file(a: Path, b: Path) -> str:
    if not a.exists() or not b.exists():
        return "missing" if a.exists() != b.exists() else "in neither"
    return "the same" if filecmp.cmp(a, b, shallow=False) else "DIFFERS"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--units", default=",".join(UNITS))
    parser.add_argument("--work", default="results/ways-identify")
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    from rapid_cosim.noise import band

    lib = band.library()
    if lib is None:
        print("the band kernel is not used on this machine: nothing to compare")
        return 1
    ways = [bit for bit in band.WAYS if lib.rc_band_ways() & bit]
    if len(ways) < 2:
        print(f"this processor has one way ({band.WAYS[ways[0]]}): nothing to compare it with")
        return 0
    ways = [ways[-1]] + ways[-2::-1]  # the processor's own choice first, then the narrower ways
    work = Path(args.work).resolve()
    bad = 0
    for name in args.units.split(","):
        base = None
        for k, way in enumerate(ways):
            folder = work / f"{name}-{band.WAYS[way].replace(' ', '-')}"
            if folder.exists():
                raise SystemExit(f"{folder} exists: give a fresh --work folder")
            seconds = identify_by(UNITS[name], folder, 0 if k == 0 else way)
            if base is None:
                base = folder
                print(f"{name}: {band.WAYS[way]} (this processor's choice) {seconds:.1f} s")
                continue
            runs, differ = differences(base, folder)
            dyr = same_file(base / "unit.dyr", folder / "unit.dyr")
            bad += len(differ) + (dyr not in ("the same", "in neither"))
            print(f"{name}: {band.WAYS[way]} forced {seconds:.1f} s; run archives the same {runs - len(differ)} of "
                  f"{runs}{' (differ: ' + ', '.join(differ) + ')' if differ else ''}; unit.dyr {dyr}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
