"""One unit's work in a fleet, whole on one worker: its record on file played back and
judged, and, where it fails or there is none (unless the fleet only checks), the unit identified as ``rapid-cosim
identify`` identifies it (the same function), its recommended record read back from the
file written, checked to be the model fitted (a unit whose file is not fails, its record
left out of ``fleet.dyr``) and played back too.

Why one worker, from scratch: a unit's result must not depend on where it ran or on a
worker lost half-way. The work folder is cleared first (a killed run's half-written
archives are never resumed by another), the identification runs in one process (one
``EngineSpec()``, seeded, the BLAS pools at one thread), so a unit redone elsewhere gives
the same numbers bit for bit.
A unit that fails gets a result with its error in its own words; nothing is raised.

A recorded event with less than :data:`QUIET_ADVISED_S` before it is flagged: that span
is all the recorder's noise is estimated from. On ``make bench-fleet``'s units recorded
from 10 s before the event, the noise tests rejected two right records of 50 at p 7e-11
and 4e-8 (with 30 s, 4 of 150 right records in three fleets, where their rates predict
3.4, and none of 150 wrong ones passed).
"""

from __future__ import annotations

import shutil
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from ..calibration.delivery import archived_reproduction
from ..compiler.source import ModelSource
from ..fitting.engine import EngineSpec, pinned_threads
from ..errors import CheckFailed, DeliveryError, RapidCosimError
from ..exchange import model_named, read_record
from ..noise import campaign_noise, quiet_windows
from ..validation.tolerances import Tolerances
from .check import check_entry
from .playback import play_back
from .result import Recommendation, Route, UnitResult
from .spec import UnitEntry

QUIET_ADVISED_S = 30.0  # of recording before an event (module docstring)
KEY = {"TGOV1": ("R", "T1", "T3", "db"), "IEEEG1": ("K", "T3", "T4", "T5", "K1", "Uo", "Uc", "db"),
       "GGOV1": ("R", "Kpgov", "Kigov", "Tb", "Ropen", "Rclose", "db"), "HYGOV": ("R", "r", "Tr", "TW", "db"),
       "GAST": ("R", "T1", "T2")}


@dataclass(frozen=True)
class FleetOptions:
    """What every unit of a fleet is run with (part of each unit's result key)."""

    results: str
    seed: int = 1
    source: ModelSource = ModelSource()  # resolved: the same paths on every worker
    pdf: bool = False
    tolerances: str | None = None
    check_only: bool = False  # play the records on file back and judge them; identify nothing


def tie_flag(recommended: str, tied_with: str | None, ties: list[str]) -> str:
    """The flag of a tie within the criterion's threshold, from the identification's
    fields: which record was recommended and which it tied with."""
    if tied_with is not None:  # a simpler record recommended in place of the first by BIC
        return f"tie: {recommended} recommended, tying with {tied_with} (the first by BIC)"
    return f"tie: {recommended} recommended (the first by BIC), {', '.join(ties)} tying with it but passed over"


def run_unit(entry: UnitEntry, options: FleetOptions) -> UnitResult:
    """The unit's result (module docstring)."""
    t0 = time.perf_counter()
    result = UnitResult(entry.name, str(entry.folder), Route.FAILED)
    work = Path(options.results) / "units" / entry.name
    try:
        if work.exists():
            shutil.rmtree(work)
        work.mkdir(parents=True)
        with pinned_threads():  # the same numbers on any worker, whatever its threads
            _run(entry, options, result, work)
    except CheckFailed as e:
        result.route, result.error = Route.FAILED, e.one_line()
    except RapidCosimError as e:
        result.route, result.error = Route.FAILED, str(e)
    except Exception as e:  # a crash is one unit's row, not the fleet's end
        result.route, result.error = Route.FAILED, f"{type(e).__name__}: {e}"
        (work / "traceback.txt").write_text(traceback.format_exc())
    result.seconds = time.perf_counter() - t0
    return result


def _run(entry: UnitEntry, options: FleetOptions, result: UnitResult, work: Path) -> None:
    from ..api import identify  # the same function as rapid-cosim identify

    checked = check_entry(entry, source=options.source)
    if not checked.ok:  # every problem of the unit's files, and nothing of it run
        raise CheckFailed(entry.name, checked.problems)
    unit = checked.unit.unit
    if checked.unsupported:  # listed, not checked: no table reads its record (nor is it re-identified)
        result.route, result.unsupported = Route.UNSUPPORTED, checked.unsupported
        result.flags.append(f"record on file is {checked.unsupported}: not supported")
        return
    tolerances = _tolerances(options)
    experiments = checked.unit.experiments
    noise = campaign_noise(experiments)
    common = dict(source=options.source, noise_fits=noise, seed=options.seed)
    on_file = None
    short = short_quiet(experiments)
    if short:
        result.flags.append(f"under {QUIET_ADVISED_S:.0f} s before the event ({', '.join(short)}): "
                            "the noise tests may pass a record a little off")
    if checked.record is not None:
        on_file = result.on_file = play_back(checked.record, experiments, list(unit.structures), tolerances,
                                             **common)
        if on_file.passed or options.check_only:
            result.route = Route.PASSED if on_file.passed else Route.FAILS
            return
    elif options.check_only:
        raise RapidCosimError(f"{entry.name}: no record on file to check (the fleet checks only)")
    ident = identify(entry.folder, workdir=work, seed=options.seed, engine=EngineSpec(), source=options.source,
                     report=True, pdf=options.pdf, log=lambda *_: None)
    result.route = Route.IDENTIFIED
    result.explanation = ident.explanation.verdict
    result.unexplained = ident.unexplained
    root = Path(options.results)
    result.files = {k: str(Path(v).resolve().relative_to(root.resolve())) for k, v in ident.files.items()}
    if result.unexplained:
        result.flags.append("unexplained")
    if ident.recommended is None:
        result.flags.append("no record recommended")
        return
    rec = ident.record(ident.recommended)
    if ident.ties:
        result.flags.append(tie_flag(ident.recommended, ident.tied_with, ident.ties))
    if rec.at_bounds:
        result.flags.append("at bounds: " + ", ".join(rec.at_bounds))
    if not rec.adequate:
        result.flags.append("not within the noise")
    for effect in rec.undetermined:  # said in the unit's story; a fleet's row says it too
        result.flags.append(f"{effect.replace('_', ' ')} not determined: the recordings do not exclude one, the "
                            "record states none" + ("; its droop may hold a band (events of two sizes separate "
                                                    "them)" if effect == "deadband" else ""))
    written = read_record(ident.files["dyr"], bus=unit.bus, machine_id=unit.machine_id)
    same = archived_reproduction(rec.archive, written)  # the file on disk is the model identify fitted
    if not same.reproduces:
        raise DeliveryError(f"{result.files['dyr']}: the record written does not reproduce the fit it was written "
                            f"from ({same.worst:.3g} pu off on {max(same.errors, key=same.errors.get)}): not "
                            "delivered")
    check = play_back(written, experiments, list(unit.structures), tolerances, **common)
    check.source = result.files["dyr"]  # relative to the results: the same wherever the fleet ran
    result.recommended = Recommendation(rec.model, rec.fit, dict(written.values),
                                        {k: written.values[k] for k in KEY.get(rec.model, ()) if k in written.values},
                                        ident.reason, check)
    if check.failing:
        result.flags.append("recommended record fails its bands on " + ", ".join(check.failing))
    result.flags.extend(f"recommended record: {why}" for why in check.inconsistent)
    result.changes = changes(on_file.values if on_file else None,
                             model_named(on_file.model).block if on_file else None, rec.model, written.values)


def short_quiet(experiments: list) -> list[str]:
    """The recorded events with less than :data:`QUIET_ADVISED_S` of quiet recording
    before the event, each with its span."""
    out = []
    for exp in experiments:
        spans = [end - start for kind, start, end, _ in quiet_windows(exp) if kind == "pre-event"]
        if spans and sum(spans) < QUIET_ADVISED_S:
            out.append(f"{exp.name}: {sum(spans):.1f} s")
    return out


def changes(old: dict | None, old_model: str | None, model: str, new: dict) -> dict[str, float | str]:
    """What the new record changes from the one on file (both by their iGrGen block: a
    TGOV1D on file is a TGOV1): the model, or each key value's relative change; a deadband
    a record does not state is none, so one added or dropped is said in words."""
    if old is None:
        return {"from": "no record on file"}
    if old_model != model:
        return {"model": f"{old_model} -> {model}"}
    out: dict[str, float | str] = {}
    for k in KEY.get(model, ()):
        a, b = (old.get(k, 0.0), new.get(k, 0.0)) if k == "db" else (old.get(k), new.get(k))
        if a is None or b is None or a == b:
            continue
        if a == 0 or b == 0:
            out[k] = f"{'none' if a == 0 else f'{a:.4g}'} -> {'none' if b == 0 else f'{b:.4g}'}"
        elif abs(b / a - 1) > 1e-3:
            out[k] = b / a - 1
    return out


def _tolerances(options: FleetOptions) -> Tolerances:
    from ..validation.tolerances import load_tolerances

    return load_tolerances(options.tolerances) if options.tolerances else Tolerances()
