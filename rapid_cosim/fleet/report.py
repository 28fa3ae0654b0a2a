"""The fleet's report: one row per unit, the failing ones first, as an HTML page (its
columns sortable by a click), ``fleet.csv`` and ``fleet.json``; and every new record in
one ``fleet.dyr`` (and in ``fleet.dyd`` each that has a PSLF record: its unit states its
MVA base, and it carries no deadband; the page names the others), ready for the
operator's case.

A row says which route the unit took (its record on file passes; it fails, where the
fleet only checks; identified; its record on file is of a model not supported, so it is
listed and not checked; failed), why the record on file fails (band metrics per
recording, the noise tests' reason), its stated false-alarm rate and the bands too noisy
to judge on its recordings (:mod:`.playback`), its RMSE over the noise, the recommended
record with its key parameters and what changed from the one on file, the flags
(unexplained, a tie, estimates on a bound, a new record that fails its bands or the
noise tests), and a link to the unit's validation report.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

from ..report.htmlkit import STYLE, e, mark
from ..diagnose.adequacy import ALPHA
from .result import Route, UnitResult
from .spec import FleetSpec

ORDER = {Route.FAILED: 0, Route.FAILS: 1, Route.IDENTIFIED: 1, Route.UNSUPPORTED: 2, Route.PASSED: 3}
ROW_CLASS = {Route.FAILED: "failed", Route.FAILS: "fails", Route.IDENTIFIED: "identified",
             Route.UNSUPPORTED: "unsupported", Route.PASSED: "passes"}
SORTER = """
document.querySelectorAll('th').forEach((th, k) => th.addEventListener('click', () => {
  const body = th.closest('table').tBodies[0], rows = [...body.rows];
  const up = th.dataset.up !== '1'; th.dataset.up = up ? '1' : '0';
  const key = r => { const c = r.cells[k]; return c.dataset.key ?? c.textContent; };
  rows.sort((a, b) => { const x = key(a), y = key(b), nx = Number(x), ny = Number(y);
    const d = isNaN(nx) || isNaN(ny) || x === '' || y === '' ? x.localeCompare(y) : nx - ny;
    return up ? d : -d; });
  rows.forEach(r => body.appendChild(r));
}));
"""


def rank(row: UnitResult) -> tuple:
    """Failing units first: failed, then failing records and identified units (flagged
    first), then the units whose record on file is of a model not supported, then passing."""
    return ORDER.get(row.route, 0), 0 if row.flags else 1, row.unit


def write_report(spec: FleetSpec, result, folder: Path) -> dict[str, str]:
    rows = sorted(result.units, key=rank)
    folder = Path(folder)
    files = {"json": folder / "fleet.json", "csv": folder / "fleet.csv", "html": folder / "fleet.html"}
    files["json"].write_text(json.dumps({"name": spec.name, "fleet": str(spec.path), "seconds": result.seconds,
                                         "workers": result.workers, "failed": result.failed,
                                         "units": [r.to_json() for r in rows]}, indent=1, default=float) + "\n")
    with open(files["csv"], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["unit", "route", "record on file", "on file passes", "why it fails", "false-alarm rate",
                    "not judged", "recommended", "key parameters", "changes", "flags", "error", "seconds", "report"])
        for r in rows:
            w.writerow([r.unit, r.route.value, _on_file_model(r), _on_file_pass(r),
                        ";".join(_failing(r)), _false_alarm(r), _not_judged(r),
                        r.recommended.fit if r.recommended else "", _key(r), _changes(r), ";".join(r.flags),
                        r.error, f"{r.seconds:.1f}", r.files.get("report", "")])
    files["html"].write_text(_page(spec, result, rows, folder))
    files.update(_records(rows, folder))
    return {k: str(v) for k, v in files.items()}


def _on_file_model(r: UnitResult) -> str:
    """The record on file's model: played back, or named as not supported."""
    return r.on_file.model if r.on_file is not None else r.unsupported


def _on_file_pass(r: UnitResult) -> str:
    return "" if r.on_file is None else "yes" if r.on_file.passed else "no"


def _failing(r: UnitResult) -> list[str]:
    """Why the record on file fails: band metrics per recording, then the noise tests."""
    if r.on_file is None:
        return []
    return ([f"{t}: {', '.join(v.failing) or 'fails'}" for t, v in r.on_file.tests.items() if not v.passed]
            + list(r.on_file.inconsistent))


def _false_alarm(r: UnitResult) -> str:
    return "" if r.on_file is None else f"{r.on_file.false_alarm:.0%}"


def _not_judged(r: UnitResult) -> str:
    """The bands too noisy to judge on the unit's recordings, with how often the noise
    alone fails them."""
    if r.on_file is None:
        return ""
    return ", ".join(f"{k} {v:.0%}" for t in r.on_file.tests.values() for k, v in t.not_judged.items())


def _key(r: UnitResult) -> str:
    return "" if r.recommended is None else ", ".join(f"{k} {v:.4g}" for k, v in r.recommended.key.items())


def _changes(r: UnitResult) -> str:
    return ", ".join(f"{k} {v:+.1%}" if isinstance(v, float) else f"{k}: {v}" for k, v in r.changes.items())


def _expected(rows: list[UnitResult]) -> str:
    """How many records on file would fail were they all correct: the sum of the rates."""
    judged = [r for r in rows if r.route is not Route.FAILED and r.on_file is not None]
    if not judged:
        return ""
    return (f"were all {len(judged)} records on file correct, about {sum(r.on_file.false_alarm for r in judged):.1f} "
            f"of them would fail (the rates' sum), {sum(not r.on_file.passed for r in judged)} did.")


def _page(spec: FleetSpec, result, rows: list[UnitResult], folder: Path) -> str:
    body = [f"<h1>Fleet {e(spec.name)}</h1>",
            f"<p id=overall>{e(result.summary())} ({result.seconds:.0f} s, {len(result.ran)} run now, {len(result.kept)} kept "
            f"from an earlier run; {result.workers} worker(s)).</p>",
            "<p class=note>Failing units first; click a column heading to sort by it. A record on file is played "
            "back on the unit's recordings and judged against the tolerance bands and against the recorder's noise "
            "(is the residual more than the noise; are the parameters where the recordings put them); a unit whose "
            "record fails, or has none, is identified as <code>rapid-cosim identify</code> identifies it (where the "
            "fleet only checks, <code>--check-only</code>, nothing is identified). "
            "<em>False-alarm rate</em>: how often a correct record would fail these checks on this unit's "
            f"recordings (the bands' rate under the recorder's noise, and the noise tests' {ALPHA:.0%}); a band "
            "the noise alone fails more than one time in ten is not judged, and named; "
            f"{_expected(rows)}{_dyr_only(rows)}</p>",
            "<table id=fleet><thead><tr><th>unit</th><th class=text>route</th><th class=text>record on file</th>"
            "<th>on file passes</th><th class=text>why it fails</th><th>false-alarm rate</th>"
            "<th class=text>not judged (the noise alone fails it)</th><th>RMSE/noise on file</th>"
            "<th class=text>recommended</th><th class=text>key parameters</th><th class=text>changes</th>"
            "<th class=text>flags</th><th>report</th></tr></thead><tbody>"]
    for r in rows:
        on = r.on_file
        rmse = max((v.rmse_over_noise for v in on.tests.values()), default=None) if on else None
        report = r.files.get("report")  # relative to the results folder, as this page
        link = f"<a href='{e(report)}'>page</a>" if report else ""
        flags = [f"error: {r.error}"] if r.route is Route.FAILED else r.flags
        body.append(f"<tr class={ROW_CLASS.get(r.route, 'failed')}><td>{e(r.unit)}</td>"
                    f"<td class=text data-key='{rank(r)[0]}'>{e(r.route.value)}</td>"
                    f"<td class=text>{e(_on_file_model(r) or 'none')}</td>"
                    f"<td data-key='{_on_file_pass(r)}'>{mark(None if on is None else on.passed)}</td>"
                    f"<td class=text>{e('; '.join(_failing(r)))}</td>"
                    f"<td data-key='{on.false_alarm if on else ''}'>{_false_alarm(r)}</td>"
                    f"<td class=text>{e(_not_judged(r))}</td>"
                    f"<td>{'' if rmse is None else f'{rmse:.2f}'}</td>"
                    f"<td class=text>{e(r.recommended.fit if r.recommended else '')}</td>"
                    f"<td class=text>{e(_key(r))}</td><td class=text>{e(_changes(r))}</td>"
                    f"<td class=text>{e('; '.join(flags))}</td><td>{link}</td></tr>")
    body.append("</tbody></table>")
    return ("<!DOCTYPE html>\n<html lang=en>\n<head><meta charset=utf-8>"
            f"<title>rapid-cosim fleet: {e(spec.name)}</title><style>{STYLE} th {{ cursor: pointer; }}"
            " tr.failed td { background: #fbeaea; } tr.fails td { background: #fdf3e1; }"
            " tr.unsupported td { color: #666; }</style></head>\n<body>\n" + "\n".join(body)
            + f"\n<script>{SORTER}</script>\n</body>\n</html>\n")


def _new_records(rows: list[UnitResult]) -> list[UnitResult]:
    return [r for r in rows if r.route is Route.IDENTIFIED and r.files.get("dyr")]


def _records(rows: list[UnitResult], folder: Path) -> dict[str, Path]:
    """Every new record in one file per format: each in fleet.dyr, and in fleet.dyd each
    that has a .dyd (one whose unit states no MVA base, or whose record carries a deadband,
    has none; the page names them)."""
    new = _new_records(rows)
    out = {}
    if not new:
        return out
    out["dyr"] = folder / "fleet.dyr"
    out["dyr"].write_text("".join((folder / r.files["dyr"]).read_text() for r in new))
    if any(r.files.get("dyd") for r in new):
        out["dyd"] = folder / "fleet.dyd"
        out["dyd"].write_text("".join((folder / r.files["dyd"]).read_text() for r in new if r.files.get("dyd")))
    return out


def _dyr_only(rows: list[UnitResult]) -> str:
    """The page's words on the new records that have no .dyd."""
    only = [r.unit for r in _new_records(rows) if not r.files.get("dyd")]
    return (f" New records only in fleet.dyr (no PSLF .dyd: no MVA base stated, or a deadband PSLF's layouts do "
            f"not carry): {', '.join(only)}." if only else "")
