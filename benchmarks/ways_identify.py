"""Whole identifications under each way of the whitener's band product (issue 42): the
processor's own choice, then every way it has forced in its place (AVX2, the pairs of
lanes every processor takes), each unit in one process, fresh folders. Every archive
(each evaluation's parameters and fitness, each fit's result) and the delivered ``.dyr``
must be the same bit for bit: what a machine without AVX-512 (or without AVX2) would
compute, run end to end on this one.

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
rc.identify(Path(sys.argv[1]), workdir=Path(sys.argv[2]), engine=rc.EngineSpec(n_jobs=1), log=lambda *a: None)
"""


def identify_by(unit: Path, folder: Path, way: int) -> float:
    """Seconds to identify ``unit`` into ``folder`` (which must not exist) with the
    several-row product taken by ``way`` (0: the processor's own choice)."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", _ONE, str(unit), str(folder), str(way)], check=True, cwd=ROOT)
    return time.perf_counter() - t0


def same_archives(a: Path, b: Path) -> tuple[int, list[str]]:
    """The number of run archives under ``a`` and those that differ from ``b``'s."""
    import h5py

    differ, n = [], 0
    for f in sorted(a.rglob("*.h5")):
        g = b / f.relative_to(a)
        with h5py.File(f) as ha:
            if "evaluations" not in ha:
                continue
            n += 1
            if not g.exists():
                differ.append(f"{f.relative_to(a)} (missing)")
                continue
            with h5py.File(g) as hb:
                if not all(np.array_equal(ha[k][:], hb[k][:])
                           for k in ("evaluations/x", "evaluations/fitness", "result/x")):
                    differ.append(str(f.relative_to(a)))
    return n, differ


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
            n, differ = same_archives(base, folder)
            dyr = filecmp.cmp(base / "unit.dyr", folder / "unit.dyr", shallow=False)
            bad += len(differ) + (not dyr)
            print(f"{name}: {band.WAYS[way]} forced {seconds:.1f} s; archives the same {n - len(differ)} of {n}"
                  f"{' (differ: ' + ', '.join(differ) + ')' if differ else ''}; unit.dyr "
                  f"{'the same' if dyr else 'DIFFERS'}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
