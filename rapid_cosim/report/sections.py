"""The validation page's sections as HTML, each from the plain data it shows (metrics and
their checks, the delivered record, the noise model, the diagnosis, the provenance).
Nothing here computes: what a section says was decided where its data were gathered."""

from __future__ import annotations

import math
from typing import Sequence

from .htmlkit import e, mark, num, table
from .provenance import Provenance
from ..validation.tolerances import LABELS, METRIC_TERMS, SOURCE_NOTE, Check, Tolerances, failure_meaning, verdict
from .unit import DeliveredRecord, DiagnosisSummary, NoiseSummary
from ..validation.metrics import ValidationMetrics

UNITS = {"rmse": "pu", "peak_change": "pu", "settled_change": "pu", "rise_time": "s", "time_to_peak": "s",
         "settling_time": "s"}


def summary(rows: Sequence[tuple[ValidationMetrics, tuple[Check, ...]]]) -> str:
    body = []
    for m, checks in rows:
        failed = [LABELS[c.metric] for c in checks if c.passed is False]
        judged = sum(c.passed is not None for c in checks)
        body.append(f'<tr data-test="{e(m.experiment)}"><td>{e(m.experiment)}</td><td class=text>{e(m.role)}</td>'
                    f"<td>{mark(verdict(checks))}</td><td>{judged} of {len(checks)}</td>"
                    f"<td class=text>{e(', '.join(failed)) or '—'}</td></tr>")
    return table(["test", "role", "result", "metrics judged", "outside the band"], body, text=(0, 1, 4))


def metrics_table(rows: Sequence[tuple[ValidationMetrics, tuple[Check, ...]]]) -> str:
    """One row per test and metric: measured, simulated, error, band, pass or fail."""
    body = []
    for m, checks in rows:
        for k, c in enumerate(checks):
            first = k == 0
            head = (f'<td rowspan={len(checks)}>{e(m.experiment)}<br><span class=note>{e(m.role)}; noise '
                    f"{num(m.noise)} pu; peak residual {num(m.peak_error)}</span></td>") if first else ""
            cls = ' class="first"' if first else ""
            body.append(f'<tr{cls} data-test="{e(m.experiment)}" data-metric="{c.metric}">{head}'
                        f"<td class=text>{e(LABELS[c.metric])} ({UNITS[c.metric]})</td><td>{num(c.measured, digits=4)}</td>"
                        f"<td>{num(c.simulated, digits=4)}</td><td>{num(c.error, sign=True)}</td>"
                        f"<td>{'—' if c.band is None else '± ' + num(c.band)}</td><td>{mark(c.passed)}</td></tr>")
    return table(["test", "metric", "measured", "simulated", "error", "band", "result"], body, text=(0, 1))


def failures_section(rows: Sequence[tuple[ValidationMetrics, tuple[Check, ...]]]) -> str:
    """Each band failed, said once per test and metric in terms of what it means for a
    study that uses the record."""
    items = [f"<li><b>{e(m.experiment)}, {e(LABELS[c.metric])}</b> (off by {num(c.error, sign=True)} "
             f"{UNITS[c.metric]}, band ± {num(c.band)}): {e(failure_meaning(c))}.</li>"
             for m, checks in rows for c in checks if c.passed is False]
    if not items:
        return ""
    return ("<h3>What the failures mean</h3><ul id=failures>" + "".join(items) + "</ul><p class=note>A failed band "
            "is a difference larger than the band allows between the simulated and the measured response on that "
            "test; whether it matters depends on the study the record is for.</p>")


def tolerance_table(tol: Tolerances) -> str:
    rows = [f'<tr data-metric="{k}"><td class="text nowrap">{e(LABELS[k])}</td><td class=text>{e(tol.describe(k))}</td>'
            f"<td class=text>{e(tol.reason(k))}</td></tr>" for k in METRIC_TERMS]
    return (table(["metric", "band (|simulated − measured| within)", "why"], rows, text=(0, 1, 2))
            + f"<p class=note>Source of the bands: {e(tol.source)}. {e(SOURCE_NOTE)}</p>")


def on_bound(value: float, searched: tuple[float, float] | None, share: float = 0.01) -> str | None:
    """"lower" or "upper" where an estimate ends within ``share`` of its range of a bound;
    a range of one sign spanning a decade or more is measured in the log, as its search
    is (a valve rate searched 0.001 to 1 pu/s is not on its bound at 0.0067)."""
    if searched is None or not searched[1] > searched[0]:
        return None
    lo, hi = searched
    sign = 1.0
    if lo * hi > 0 and max(abs(lo), abs(hi)) >= 10 * min(abs(lo), abs(hi)) and value * lo > 0:
        sign = 1.0 if lo > 0 else -1.0  # a negative range's bound nearest zero is its upper one
        lo, hi, value = sorted((math.log(abs(lo)), math.log(abs(hi)))) + [math.log(abs(value))]
    if min(value - lo, hi - value) > share * (hi - lo):
        return None
    return "lower" if (value - lo < hi - value) == (sign > 0) else "upper"


def record_section(rec: DeliveredRecord, interval_note: str, level: float | None) -> str:
    parts = []
    if rec.model is None:
        parts.append(f"<p>No standard record: {e(rec.note)}</p>")
    else:
        parts.append(f"<p>Standard model: <b>{e(rec.model)}</b>. {e(rec.note)}</p>")
        parts.append(f'<h3>PSS/E .dyr</h3><pre class="record dyr">{e(rec.dyr)}</pre>')
        if rec.dyd is not None:
            parts.append(f'<h3>PSLF .dyd</h3><pre class="record dyd">{e(rec.dyd)}</pre>')
    lvl = f"{100 * level:.0f} % interval" if level is not None else "interval"
    rows, held = [], []
    for p in rec.parameters:
        interval = "—" if p.interval is None else f"{p.interval[0]:.4g} … {p.interval[1]:.4g}"
        searched = "—" if p.searched is None else f"{p.searched[0]:g} … {p.searched[1]:g}"
        bound = on_bound(p.value, p.searched)
        if bound:
            held.append(f"{p.label or p.name} = {p.value:.4g} is on the {bound} bound of its search range")
        rows.append(f'<tr data-origin="{e(p.origin)}"><td><code>{e(p.name)}</code></td><td class=text>{e(p.label)}</td>'
                    f"<td>{p.value:.5g}{f' <b class=bound>on {bound} bound</b>' if bound else ''}</td>"
                    f"<td class=text>{e(p.origin)}</td><td>{interval}</td><td>{searched}</td></tr>")
    parts.append("<h3>Parameters</h3>" + table(["parameter", "label", "value", "origin", lvl, "searched"], rows,
                                                text=(0, 1, 3)))
    if held:
        parts.append(f"<p id=bounds class=warn>{e('; '.join(held))}: the range, not the data, holds it there, and "
                     "its interval is the range's as much as the data's. Widen the range where the plant allows; "
                     "where the documentation sets the bound, the record states the documented limit.</p>")
    parts.append("<p class=note>Estimated: calibrated on the training tests. Documented: fixed in the experiments' "
                 "configs (the unit's documented constants). Bench default: neither, the model's own value, "
                 "written in the record as it stands; one with no field in the record (an operating point or a "
                 "smooth limit's sharpness) is not written, and the grid simulator uses its own "
                 f"(rapid_cosim.exchange.tables). {e(interval_note)}</p>")
    return "\n".join(parts)


def recording_section(lines: Sequence[str]) -> str:
    """What each power column was taken to be, where it is electrical power."""
    return f"<ul id=recorded class=note>{''.join(f'<li>{e(w)}</li>' for w in lines)}</ul>" if lines else ""


def timebase_section(recordings: Sequence[tuple[str, Sequence[str]]]) -> str:
    """Per test, what its recording's stamps are and what was repaired, masked or bridged."""
    items = "".join(f"<li><b>{e(name)}</b>: {'; '.join(e(w) for w in lines)}</li>" for name, lines in recordings)
    return ("<h3>The recordings as recorded</h3><ul id=timebase class=note>" + items + "</ul>"
            "<p class=note>Nothing is repaired silently: a repeated stamp is dropped only where its values agree, a "
            "late frame sorted only within a frame; masked samples are out of the fit and out of the ROCOF's "
            "windows; input holes are bridged by interpolation.</p>") if items else ""


def noise_section(noise: NoiseSummary) -> str:
    rows = [f"<tr><td class=text>{e(', '.join(r.tests))}</td><td class=text>{e(r.family)}</td>"
            f"<td class=text>{e(r.description)}</td><td class=text>{e(r.detail)}</td></tr>" for r in noise.rows]
    levels = ", ".join(f"{k} {v:.3g}" for k, v in noise.levels.items())
    out = f"<p>Noise model: {e(noise.source)}.</p>"
    if rows:
        out += table(["tests", "family", "model", "from"], rows, text=(0, 1, 2, 3))
    if levels:
        out += f"<p class=note>Pre-event noise level per test (pu, the metrics' scale): {e(levels)}.</p>"
    return out


def diagnosis_section(d: DiagnosisSummary | None) -> str:
    if d is None:
        return ("<p class=note>No diagnosis given (rapid-cosim diagnose writes one; pass it with "
                "--diagnosis results/diagnose/diagnosis.json).</p>")
    rows = [f"<tr><td>{e(t.test)}</td><td>{t.variance_ratio:.3g}</td><td>{t.rmse_over_noise:.3g}</td>"
            f"<td>{t.p:.3g}</td><td>{t.p_holm:.3g}</td><td>{mark(t.adequate)}</td></tr>" for t in d.tests]
    noise = "".join(f"<li>{e(n)}</li>" for n in d.noise)
    return (f"<p>Verdict of <code>{e(d.path)}</code>: <b>{e(d.verdict)}</b>; the final model is "
            f"{'adequate' if d.adequate else 'not adequate'} (campaign p = {d.p:.3g} against α = {d.alpha:g}, "
            f"pooled variance ratio {d.pooled_variance_ratio:.3g}). {e(d.reason)}</p>"
            + table(["test", "variance ratio", "RMSE / noise", "p", "p (Holm)", "adequate"], rows)
            + (f"<p class=note>The diagnosis's noise models:</p><ul class=note>{noise}</ul>" if noise else ""))


def provenance_section(p: Provenance) -> str:
    rows = [f"<tr><td>{e(f.experiment)}</td><td class=text><code>{e(f.path)}</code></td>"
            f"<td class=text><code>{e(f.sha256 or 'not on disk: the archived copy was used')}</code></td></tr>"
            for f in p.files]
    archived = [f"<tr><td>{e(k)}</td><td class=text>archived data</td><td class=text><code>{e(v)}</code></td></tr>"
                for k, v in p.archived_data.items()]
    versions = ", ".join(f"{k} {v}" for k, v in p.versions.items())
    return (f"<p>Archive <code>{e(p.archive)}</code>, SHA-256 <code>{e(p.archive_sha256)}</code>.</p>"
            + table(["experiment", "file", "SHA-256"], rows + archived, text=(0, 1, 2))
            + f"<p class=note>Computed with {e(versions)}; {e(p.python)}.</p>")
