"""Random damage to archives, and what the commands make of it (the fuzz test's engine;
``tests/test_archive_fuzz.py`` runs a small count, ``make test-slow`` and
``benchmarks/archive_bench.py --fuzz`` the full one).

Each trial damages a copy of an archive in one of three ways (bytes flipped at random
offsets, a block zeroed, the file cut short at a random offset) and runs ``show``,
``verify``, ``rerun``, ``resume`` and ``table1`` on it in this process, each under a
time limit. An outcome is one of:

* ``correct``: the command succeeded and its result is the undamaged archive's (show's
  summary, rerun's bit-for-bit verdict, resume's final result, table1's row), or verify
  said intact and the damage touched no stored content (spare room of a live archive);
* ``error``: one clear line (``rapid-cosim CMD: error: ...``), no traceback;
* ``traceback``, ``hang``, ``silent`` (success with a result other than the undamaged
  one): the failures the test counts and must not see.
"""

from __future__ import annotations

import contextlib
import io
import json
import random
import shutil
import signal
from collections import Counter
from pathlib import Path

import numpy as np

from rapid_cosim.archive import RunArchive
from rapid_cosim.cli import main

COMMANDS = ("show", "verify", "rerun", "resume", "table1")


def damage(path: Path, rng: random.Random) -> str:
    size = path.stat().st_size
    kind = rng.choice(("flip", "zero", "truncate"))
    data = bytearray(path.read_bytes())
    if kind == "flip":
        for _ in range(rng.randint(1, 16)):
            data[rng.randrange(size)] ^= 1 << rng.randrange(8)
    elif kind == "zero":
        start, length = rng.randrange(size), rng.randint(1, 4096)
        data[start:start + length] = bytes(len(data[start:start + length]))
    else:
        data = data[:rng.randrange(size)]
    path.write_bytes(bytes(data))
    return kind


class _Hang(Exception):
    pass


def _on_alarm(signum, frame):
    raise _Hang()


def run_command(argv: list[str], seconds: int = 60) -> tuple[int | str, str, str]:
    """(exit code, or 'traceback'/'hang'; stdout; stderr) of one CLI command in-process."""
    out, err = io.StringIO(), io.StringIO()
    old = signal.signal(signal.SIGALRM, _on_alarm)
    signal.alarm(seconds)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code: int | str = main(argv)
    except _Hang:
        code = "hang"
    except BaseException as e:  # what a user would see as a traceback
        code = "traceback"
        err.write(f"{type(e).__name__}: {e}")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    return code, out.getvalue(), err.getvalue()


def _summary(path: Path) -> dict:
    code, out, _ = run_command(["show", str(path), "--json", str(path.with_suffix(".json"))])
    assert code == 0, out
    return json.loads(path.with_suffix(".json").read_text())


def classify(command: str, code, out: str, err: str, work: Path, reference: dict) -> str:
    if code in ("traceback", "hang"):
        return code
    errors = [ln for ln in err.splitlines() if ": error: " in ln]
    if code == 2:
        return "error" if len(errors) == 1 and "Traceback" not in err else "traceback"
    if command == "verify":
        return "correct" if code in (0, 1) else "traceback"
    if code != 0:
        return "silent"  # rerun's "DIFFERENT": damage that went unnoticed until the re-run
    if command == "show":
        got = json.loads((work / "show.json").read_text())
        keys = ("best", "best_fitness", "nfev", "nit", "status")
        return "correct" if {k: got[k] for k in keys} == {k: reference["summary"][k] for k in keys} else "silent"
    if command == "rerun":
        return "correct"  # "identical": every archived iteration passed its checksum and matched
    if command == "resume":
        with RunArchive(work / "archive.h5") as view:
            result = view.result()
        same = result is not None and np.array_equal(result.x, reference["x"]) and result.fun == reference["fun"]
        return "correct" if same else "silent"
    return "correct"  # table1 printed rows read through the checksummed result


def fuzz(archives: dict[str, Path], expected: dict[str, dict], n: int, work: Path, seed: int = 0,
         log=lambda *_: None) -> Counter:
    """``n`` trials spread over ``archives`` (label -> undamaged archive); ``expected``
    holds, per label, the undamaged summary and the final x and fun of its run."""
    rng = random.Random(seed)
    tally: Counter = Counter()
    labels = list(archives)
    for trial in range(n):
        label = labels[trial % len(labels)]
        damaged = work / f"t{trial}" / "damaged.h5"
        damaged.parent.mkdir(parents=True)
        shutil.copyfile(archives[label], damaged)
        kind = damage(damaged, rng)
        for command in COMMANDS:  # the same damage through every command
            folder = work / f"t{trial}" / command
            folder.mkdir(parents=True)
            target = folder / "archive.h5"
            shutil.copyfile(damaged, target)
            if command == "table1":
                (folder / "test1").mkdir()
                for stem in ("pso10+nm", "pf10+nm"):
                    shutil.copyfile(target, folder / "test1" / f"{stem}.h5")
                argv = ["table1", "--results", str(folder), "--tests", "1"]
            elif command == "show":
                argv = ["show", str(target), "--json", str(folder / "show.json")]
            else:
                argv = [command, str(target)] + (["--quiet"] if command in ("rerun", "resume") else [])
            code, out, err = run_command(argv)
            outcome = classify(command, code, out, err, folder, expected[label])
            tally[outcome] += 1
            tally[f"{label}/{command}/{outcome}"] += 1
            if outcome in ("traceback", "hang", "silent"):
                log(f"trial {trial} ({label}, {kind}) {command}: {outcome}: {err.strip()[-300:]}")
        shutil.rmtree(work / f"t{trial}", ignore_errors=True)
    return tally


def expected_of(path: Path, reference_result) -> dict:
    return {"summary": _summary(path), "x": np.asarray(reference_result.x), "fun": reference_result.fun}
