"""A fleet run: every unit of a fleet file on a dask cluster, one unit per task, each
result written as it finishes, so that a run stopped anywhere resumes where it stopped.

Why by units: a unit's work (its record played back, and where needed its whole
identification) is hundreds of simulations in one process; spread over workers it
would be no faster and its numbers would depend on where each batch ran. A task is one
unit, whole (:func:`.unit_job.run_unit`); dask runs the tasks of a lost worker again on
another, and the unit's result is the same bit for bit.

Resume: a unit's result file records a digest of everything it was made from (the
unit's folder, its configs' data files, its record on file, the options, and the
rapid-cosim version and judging rules that made it); a result whose digest still matches is kept, any
other unit is run.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import tomllib
from dataclasses import asdict
from pathlib import Path
from typing import Callable

from ..compiler.source import ModelSource
from ..fitting.engine import EngineSpec
from ..progress import Stage
from ..version import __version__
from .playback import RULES
from .spec import FleetSpec, UnitEntry, load_fleet
from .result import FleetResult, UnitResult
from .unit_job import FleetOptions, run_unit


def common_digest(options: FleetOptions) -> bytes:
    """What every unit's digest ends with: the options, the models by their sources (not
    by where they lie: a fleet run again from another folder keeps its units), the
    version and the rules. Read once per fleet, not once per unit (the package's every
    source file)."""
    parts = [json.dumps({k: v for k, v in asdict(options).items() if k not in ("results", "source")},
                        sort_keys=True).encode(), options.source.digest().encode()]
    if options.source.compiler != "auto":  # another compiler, other FMUs (auto: as every earlier run)
        parts.append(options.source.compiler.encode())
    parts.append(f"{__version__}; {RULES}".encode())  # another version or rule may judge or identify differently
    return b"".join(parts)


def unit_digest(entry: UnitEntry, options: FleetOptions, common: bytes | None = None) -> str:
    """A digest of what a unit's result is made from (module docstring); ``common``:
    :func:`common_digest` of ``options``, where the caller has it."""
    h = hashlib.blake2b(digest_size=16)
    files = sorted(p for p in entry.folder.rglob("*") if p.is_file())
    for config in entry.folder.rglob("config.toml"):  # recordings a config reads from outside the folder
        try:
            raw = tomllib.loads(config.read_text())
        except (OSError, tomllib.TOMLDecodeError):
            continue
        named = [raw.get("data", {}).get("file")] + [v.get("file") for v in raw.get("inputs", {}).values()
                                                     if isinstance(v, dict)]
        files += [(config.parent / n.split(":")[0]).resolve() for n in named if isinstance(n, str)]
    if entry.record is not None:
        files.append(entry.record)
    for path in dict.fromkeys(files):
        if path.is_file():
            h.update(str(path.name).encode())
            h.update(path.read_bytes())
    h.update(common_digest(options) if common is None else common)
    return h.hexdigest()


def run_fleet(fleet: str | Path, *, results: str | Path, engine: EngineSpec = EngineSpec(),
              seed: int = 1, source: ModelSource = ModelSource(), pdf: bool = False, check_only: bool = False,
              progress: bool = True, log: Callable[[str], None] = print) -> FleetResult:
    """Run (or resume) the fleet of ``fleet`` into ``results``: each unit's result in
    ``results/units/<unit>.json`` as it finishes, then the fleet's report
    (:mod:`.report`). The units are mapped over a dask cluster: ``engine``'s scheduler's,
    else a LocalCluster of ``engine.n_jobs`` processes on this machine (the default engine,
    one: the units one after the other); each unit runs in
    one worker, alone (:func:`~.unit_job.run_unit`). ``check_only``: the records on file are
    played back and judged, and nothing is identified (a failing record's row says so)."""
    from .report import write_report

    spec = load_fleet(fleet)
    workers = engine.workers()
    results = Path(results)
    folder = results / "units"
    folder.mkdir(parents=True, exist_ok=True)
    source = source.resolved()  # the workers' paths, whatever their folder
    options = FleetOptions(str(results.resolve()), seed, source, pdf, str(spec.tolerances) if spec.tolerances else None, check_only)
    t0 = time.perf_counter()
    done, todo, common = {}, [], common_digest(options)
    for entry in spec.units:
        digest = unit_digest(entry, options, common)
        kept = _read(folder / f"{entry.name}.json")
        if kept is not None and kept.digest == digest:
            done[entry.name] = kept
        else:
            todo.append((entry, digest))
    log(f"fleet {spec.name}: {len(spec.units)} units, {len(done)} already done, {len(todo)} to run on "
        + (f"the cluster at {engine.scheduler}" if engine.scheduler else f"{workers} local worker(s)"))
    if todo:
        _build_benches(spec, source)
        done.update(_distribute(todo, options, folder, engine, progress))
    units = [done[e.name] for e in spec.units]
    result = FleetResult(spec.name, units, [e.name for e, _ in todo], [n for n in done if n not in
                                                                        {e.name for e, _ in todo}],
                         time.perf_counter() - t0, workers)
    result.files = write_report(spec, result, results)
    return result


def _distribute(todo, options: FleetOptions, folder: Path, engine: EngineSpec,
                progress: bool) -> dict[str, UnitResult]:
    from distributed import as_completed

    out = {}
    with engine.client() as client:
        futures = {client.submit(run_unit, entry, options, key=f"unit-{entry.name}-{digest[:12]}", retries=3):
                   (entry, digest) for entry, digest in todo}
        with Stage("units", len(todo), unit="unit", enabled=progress) as bar:
            for future in as_completed(futures):
                entry, digest = futures[future]
                row = future.result()
                row.digest = digest
                _write(folder / f"{entry.name}.json", row.to_json())  # kept as it finishes: a rerun skips it
                out[entry.name] = row
                bar.update(1, f"{entry.name}: {row.route.value}")
    return out


def _build_benches(spec: FleetSpec, source: ModelSource) -> None:
    """Every bench the units name, built once here rather than raced by the workers."""
    from ..experiment import load_experiment
    from ..identify import Unit

    models = set()
    for entry in spec.units:
        try:
            unit = Unit.load(entry.folder)
            models.update(m for m in (load_experiment(c).model for c in unit.configs) if m.startswith("iGrGen."))
        except Exception:  # a bad unit is reported by its own task
            continue
    structures = [f"iGrGen.TestBenches.FrequencyInput{s}" for s in ("", "TGOV1", "IEEEG1", "GGOV1", "HYGOV")]
    source.build(sorted(models | set(structures)))


def _read(path: Path) -> UnitResult | None:
    """A unit's result as written (None: none, or one this version cannot read: run again)."""
    try:
        return UnitResult.from_json(json.loads(path.read_text()))
    except (OSError, ValueError, TypeError, KeyError):
        return None


def _write(path: Path, data: dict) -> None:
    tmp = path.with_suffix(".json.part")
    tmp.write_text(json.dumps(data, indent=1, default=float) + "\n")
    os.replace(tmp, path)  # a result file is whole or absent
