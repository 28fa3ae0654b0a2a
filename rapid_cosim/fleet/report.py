"""The fleet's report: one row per unit, the failing ones first, as an HTML page (its
columns sortable by a click), ``fleet.csv`` and ``fleet.json``; and every new record in
one ``fleet.dyr`` (and ``fleet.dyd`` where every new record's unit states its MVA base),
ready for the operator's case.

A row says which path the unit took (its record on file passes; it fails, where the
fleet only checks; identified; failed), why the record on file fails (band metrics per
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
from .spec import FleetSpec
from .unit_job import FAILED, FAILS, IDENTIFIED, PASSED

ORDER = {FAILED: 0, FAILS: 1, IDENTIFIED: 1, PASSED: 2}
ROW_CLASS = {FAILED: "failed", FAILS: "fails", IDENTIFIED: "identified", PASSED: "passes"}
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


def rank(row: dict) -> tuple:
    """Failing units first: failed, then failing records and identified units (flagged
    first), then passing."""
    return ORDER.get(row["path"], 0), 0 if row.get("flags") else 1, row["unit"]


def write_report(spec: FleetSpec, result, folder: Path) -> dict[str, str]:
    rows = sorted(result.units, key=rank)
    folder = Path(folder)
    files = {"json": folder / "fleet.json", "csv": folder / "fleet.csv", "html": folder / "fleet.html"}
    files["json"].write_text(json.dumps({"name": spec.name, "fleet": str(spec.path), "seconds": result.seconds,
                                         "workers": result.workers, "failed": result.failed, "units": rows},
                                        indent=1, default=float) + "\n")
    with open(files["csv"], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["unit", "path", "record on file", "on file passes", "why it fails", "false-alarm rate", "not judged",
                    "recommended", "key parameters", "changes", "flags", "error", "seconds", "report"])
        for r in rows:
            w.writerow([r["unit"], r["path"], (r.get("on_file") or {}).get("model", ""), _on_file_pass(r),
                        ";".join(_failing(r)), _false_alarm(r), _not_judged(r),
                        (r.get("recommended") or {}).get("fit", ""), _key(r), _changes(r),
                        ";".join(r.get("flags", [])), r.get("error", ""), f"{r.get('seconds', 0):.1f}",
                        r.get("files", {}).get("report", "")])
    files["html"].write_text(_page(spec, result, rows, folder))
    files.update(_records(rows, folder))
    return {k: str(v) for k, v in files.items()}


def _on_file_pass(r: dict) -> str:
    on = r.get("on_file")
    return "" if on is None else "yes" if on["passed"] else "no"


def _failing(r: dict) -> list[str]:
    """Why the record on file fails: band metrics per recording, then the noise tests."""
    on = r.get("on_file") or {}
    return ([f"{t}: {', '.join(v['failing']) or 'fails'}" for t, v in on.get("tests", {}).items() if not v["passed"]]
            + list(on.get("inconsistent", [])))


def _false_alarm(r: dict) -> str:
    on = r.get("on_file")
    return "" if on is None or "false_alarm" not in on else f"{on['false_alarm']:.0%}"


def _not_judged(r: dict) -> str:
    """The bands too noisy to judge on the unit's recordings, with how often the noise
    alone fails them."""
    on = r.get("on_file") or {}
    return ", ".join(f"{k} {v:.0%}" for t in on.get("tests", {}).values() for k, v in t.get("not_judged", {}).items())


def _key(r: dict) -> str:
    rec = r.get("recommended") or {}
    return ", ".join(f"{k} {v:.4g}" for k, v in rec.get("key", {}).items())


def _changes(r: dict) -> str:
    c = r.get("changes") or {}
    return ", ".join(f"{k} {v:+.1%}" if isinstance(v, float) else f"{k}: {v}" for k, v in c.items())


def _expected(rows: list[dict]) -> str:
    """How many records on file would fail were they all correct: the sum of the rates."""
    rates = [r["on_file"]["false_alarm"] for r in rows
             if r["path"] != FAILED and (r.get("on_file") or {}).get("false_alarm") is not None]
    if not rates:
        return ""
    return (f"were all {len(rates)} records on file correct, about {sum(rates):.1f} of them would fail "
            f"(the rates' sum), {sum(r['path'] != FAILED and not r['on_file']['passed'] for r in rows if r.get('on_file'))} "
            "did.")


def _page(spec: FleetSpec, result, rows: list[dict], folder: Path) -> str:
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
            f"{_expected(rows)}</p>",
            "<table id=fleet><thead><tr><th>unit</th><th class=text>path</th><th class=text>record on file</th>"
            "<th>on file passes</th><th class=text>why it fails</th><th>false-alarm rate</th>"
            "<th class=text>not judged (the noise alone fails it)</th><th>RMSE/noise on file</th>"
            "<th class=text>recommended</th><th class=text>key parameters</th><th class=text>changes</th>"
            "<th class=text>flags</th><th>report</th></tr></thead><tbody>"]
    for r in rows:
        on = r.get("on_file")
        rmse = max((v["rmse_over_noise"] for v in (on or {}).get("tests", {}).values()), default=None)
        report = r.get("files", {}).get("report")  # relative to the results folder, as this page
        link = f"<a href='{e(report)}'>page</a>" if report else ""
        flags = r.get("flags", [])
        if r["path"] == FAILED:
            flags = [f"error: {r.get('error', '')}"]
        body.append(f"<tr class={ROW_CLASS.get(r['path'], 'failed')}><td>{e(r['unit'])}</td>"
                    f"<td class=text data-key='{rank(r)[0]}'>{e(r['path'])}</td>"
                    f"<td class=text>{e((on or {}).get('model', 'none'))}</td>"
                    f"<td data-key='{_on_file_pass(r)}'>{mark(None if on is None else on['passed'])}</td>"
                    f"<td class=text>{e('; '.join(_failing(r)))}</td>"
                    f"<td data-key='{(on or {}).get('false_alarm', '')}'>{_false_alarm(r)}</td>"
                    f"<td class=text>{e(_not_judged(r))}</td>"
                    f"<td>{'' if rmse is None else f'{rmse:.2f}'}</td>"
                    f"<td class=text>{e((r.get('recommended') or {}).get('fit', ''))}</td>"
                    f"<td class=text>{e(_key(r))}</td><td class=text>{e(_changes(r))}</td>"
                    f"<td class=text>{e('; '.join(flags))}</td><td>{link}</td></tr>")
    body.append("</tbody></table>")
    return ("<!DOCTYPE html>\n<html lang=en>\n<head><meta charset=utf-8>"
            f"<title>rapid-cosim fleet: {e(spec.name)}</title><style>{STYLE} th {{ cursor: pointer; }}"
            " tr.failed td { background: #fbeaea; } tr.fails td { background: #fdf3e1; }</style></head>\n<body>\n" + "\n".join(body)
            + f"\n<script>{SORTER}</script>\n</body>\n</html>\n")


def _records(rows: list[dict], folder: Path) -> dict[str, Path]:
    """Every new record in one file per format (a .dyd only where every unit states its MVA)."""
    new = [r for r in rows if r["path"] == IDENTIFIED and r.get("files", {}).get("dyr")]
    out = {}
    if not new:
        return out
    out["dyr"] = folder / "fleet.dyr"
    out["dyr"].write_text("".join((folder / r["files"]["dyr"]).read_text() for r in new))
    if all(r["files"].get("dyd") for r in new):
        out["dyd"] = folder / "fleet.dyd"
        out["dyd"].write_text("".join((folder / r["files"]["dyd"]).read_text() for r in new))
    return out

