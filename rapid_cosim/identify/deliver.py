"""What an identification hands to its validation report: the held-out tests on the
recommended record's bench, written as configs, the explanation as a diagnosis, and the
words above the record.

Why written as files: the report is the one ``rapid-cosim report`` writes (from the
recommended fit's archive, :func:`rapid_cosim.report.html.validation_page`), and with
these files a reader can remake it by that command alone. The held-out configs are the
tests exactly as the selection predicted them
(:func:`rapid_cosim.structures.structure.on_structure`: the structure's bench and
constants, the recorder's noise model), so the page judges the record delivered, not a
re-fit of it.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Sequence

from ..calibration.delivery import plain_departure
from ..exchange import Record
from ..experiment import Experiment, render_config
from .result import Identification

NO_DYD = ("no MVA base for the unit (a .dyd record states it): set [unit] mva in the unit file, or pass "
          "--mva MVA (make identify MVA=...)")


def write_configs(experiments: Sequence[Experiment], folder: str | Path) -> list[Path]:
    """Each experiment of :meth:`Structure.experiment` at ``folder/<name>/config.toml``,
    its data and input files named by absolute path (so the config reads the same from
    anywhere): its data file is named from the working folder already (the structure's
    config moved it), its inputs' files still from the original config's folder."""
    paths = []
    for exp in experiments:
        sections = tomllib.loads(exp.config_text)
        home = Path(exp.config_path).parent
        sections["data"]["file"] = str(Path(sections["data"]["file"]).resolve())
        for spec in sections.get("inputs", {}).values():
            if isinstance(spec, dict) and isinstance(spec.get("file"), str):
                spec["file"] = str((home / spec["file"]).resolve())
        path = Path(folder) / exp.name / "config.toml"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(render_config(sections))
        paths.append(path)
    return paths


def layout_note(archive: str | Path, layout: str, record: Record) -> str:
    """The words for a record in a layout of its own (TGOV1D): who reads it, and what a
    simulator that reads only the plain model loses, measured on the unit's own tests
    (:func:`~rapid_cosim.calibration.delivery.plain_departure`)."""
    departs = plain_departure(archive, record)
    test, (miss, span) = max(departs.items(), key=lambda kv: kv[1][0])
    return (f"{layout} ({record.block}'s fields, then its deadband db = {record.values['db']:.3g} pu of speed as "
            f"dbH = -dbL, then Trate): PowerWorld and ORNL GridKit read this layout; a simulator that reads only "
            f"{record.block} loses the band: played without it, the record departs from its fit by up to "
            f"{miss:.3g} pu on {test} ({100 * miss / span:.0f} % of the response there)")


def record_note(result: Identification) -> str:
    """Above the report's record: whose record it is, why it was chosen, how close it
    comes per test (RMSE over the recorder's noise level, as the identification judged)."""
    r = result.record(result.recommended)
    fidelity = r.fidelity([*result.training, *result.heldout])
    said = "".join(f"; {c}" for c in r.cautions) if r.adequate else ""  # the reason has said the fidelity
    return (f"The record rapid-cosim identify recommends for {result.unit}: {r.model}"
            + (f" ({r.fit})" if r.fit != r.model else "") + f", {result.reason}{said}. RMSE over the noise "
            f"per test: {fidelity}" + (f" (held out: {', '.join(result.heldout)})" if result.heldout else "") + "."
            + (f" Written as {result.layout_note}." if result.layout_note else ""))
