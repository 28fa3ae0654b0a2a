"""What an identification hands over: the recommended record in the grid operator's
formats, and the validation report of that record.

The records are what ``rapid-cosim export`` writes of the recommended fit's archive
(:func:`rapid_cosim.api.export`); the report is what ``rapid-cosim report`` writes of it
(:func:`rapid_cosim.campaign.validation_page`), with the unit's held-out tests predicted
on the record's own bench exactly as the selection predicted them
(:func:`rapid_cosim.diagnose.structures.on_structure`), and the explanation as its
diagnosis. So the page judges the record that was delivered, not a re-fit of it.

Why a missing Chromium costs only the PDF: the identification took minutes and the HTML
page is the same document; the reason is said where the PDF would be listed.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from ..errors import RapidCosimError
from ..experiment import Experiment
from .result import Identification
from .unit import Unit

NO_DYD = ("no MVA base for the unit (a .dyd record states it): set [unit] mva in the unit file, or pass "
          "--mva MVA (make identify MVA=...; rc.identify(..., mva=...))")


@dataclass(frozen=True)
class Delivery:
    """What to write besides the records, and with what."""

    report: bool = True
    pdf: bool = True
    n_jobs: int = 1
    package: str | Path = "modelica/iGrGen"
    fmu_dir: str | Path = "fmus"


def pdf_unavailable(delivery: Delivery) -> str | None:
    """Why no PDF can be printed (None: it can), asked before the work starts so the
    user hears it at once and again in the story."""
    if not delivery.report:
        return "no report (--no-report)"
    if not delivery.pdf:
        return "not asked for (--no-pdf)"
    from ..report.pdf import ChromiumMissing, chromium

    try:
        chromium()
    except ChromiumMissing as e:
        return str(e)
    return None


def deliver(result: Identification, unit: Unit, heldout: Sequence[Experiment], explanation: dict | None,
            folder: str | Path, delivery: Delivery, *, log: Callable[[str], None] = print) -> Identification:
    """Write the recommended record (``unit.dyr``, and ``unit.dyd`` where the MVA base is
    known) and its validation report (``report.html``, ``report.pdf``) into ``folder``;
    ``heldout``: the held-out tests on the recommended record's bench; ``explanation``:
    the explanation's diagnosis as JSON. Records in ``result.files``, the reason for
    anything not written in ``result.notes``."""
    from ..api import export

    folder = Path(folder)
    if result.recommended is None:
        result.notes.update(dyr="no record recommended", dyd="no record recommended")
        return result
    record = result.record(result.recommended)
    for kind in ("dyr", "dyd") if unit.mva is not None else ("dyr",):  # a .dyd states the MVA base
        written = export(record.archive, folder / f"unit.{kind}", bus=unit.bus, machine_id=unit.machine_id,
                         mva=unit.mva)
        result.files[kind] = str(written.path)
    if unit.mva is None:
        result.notes["dyd"] = NO_DYD
    why_no_pdf = pdf_unavailable(delivery)
    if not delivery.report:
        result.notes["report"] = "not asked for (--no-report)"
        return result
    diagnosis = None
    if explanation is not None:
        diagnosis = folder / "explanation" / "diagnosis.json"
        diagnosis.parent.mkdir(parents=True, exist_ok=True)
        diagnosis.write_text(json.dumps(explanation, indent=2) + "\n")
    log(f"the validation report of {record.fit} ...")
    from ..campaign import validation_page

    page = validation_page(record.archive, folder / "report.html", n_jobs=delivery.n_jobs, heldout=tuple(heldout),
                           diagnosis=diagnosis, bus=unit.bus, machine_id=unit.machine_id, mva=unit.mva,
                           package=delivery.package, fmu_dir=delivery.fmu_dir, record_note=record_note(result))
    result.files["report"] = str(page.path)
    if why_no_pdf is not None:
        result.notes["pdf"] = why_no_pdf
        return result
    from ..report.pdf import print_pdf

    try:
        result.files["pdf"] = str(print_pdf(page.path, folder / "report.pdf"))
    except RapidCosimError as e:  # Chromium found but failed: the HTML stands
        result.notes["pdf"] = str(e)
        log(f"  no PDF: {e}")
    return result


def record_note(result: Identification) -> str:
    """Above the report's record: whose record it is, why it was chosen, how close it
    comes per test (RMSE over the recorder's noise level, as the identification judged)."""
    r = result.record(result.recommended)
    fidelity = ", ".join(f"{t} {r.tests[t]['rmse_over_noise']:.2f}" for t in [*result.training, *result.heldout]
                         if t in r.tests)
    return (f"The record rapid-cosim identify recommends for {result.unit}: {r.model}"
            + (f" ({r.fit})" if r.fit != r.model else "") + f", {result.reason}; {r.words}. RMSE over the noise "
            f"per test: {fidelity}" + (f" (held out: {', '.join(result.heldout)})" if result.heldout else "") + ".")
