"""The validation page of a calibrated unit: one self-contained HTML file.

It holds the parameters with their intervals, every experiment's error metrics
(:mod:`.validation`) and its figure (recorded inputs, measured and simulated output,
residuals). The figures are PNGs embedded as base64 ``data:`` URIs and the style sheet
is inline, so the page opens offline, can be mailed, and is archived as one file.
"""

from __future__ import annotations

import base64
import html
import io
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Sequence

import numpy as np

from .. import __version__
from ..estimators.uncertainty import Uncertainty
from .archives import ArchivedRun, caption, curves_at
from .figures import plt
from .fits import plot_experiment
from .validation import ValidationMetrics, metrics

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 60em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.92em; }
th, td { padding: 0.25em 0.7em; border-bottom: 1px solid #e4e4e4; text-align: right; }
th:first-child, td:first-child { text-align: left; }
img { max-width: 100%; display: block; margin: 0.5em 0 1.5em; }
.note { color: #555; font-size: 0.9em; }
"""


@dataclass(frozen=True)
class ValidationPage:
    path: Path
    metrics: tuple[ValidationMetrics, ...]
    n_figures: int


def write_validation_page(run: ArchivedRun, out: str | Path, *, uncertainty: Uncertainty | None = None,
                          interval_note: str = "") -> ValidationPage:
    """``out`` (.html) for the archived ``run``; ``uncertainty`` gives the intervals when
    the run's own method gave none (``interval_note`` says where they come from)."""
    out = Path(out)
    problem = run.inputs.problem
    x = np.asarray(run.result.x, dtype=float)
    unc = run.result.uncertainty or uncertainty
    sections, rows = [], []
    for i, exp in enumerate(problem.experiments):
        c = curves_at(run.inputs, x, i)
        m = metrics(c)
        rows.append(m)
        fig = plot_experiment(exp, c, title=caption(exp))
        sections.append(f"<h3>{_e(caption(exp))}</h3>\n<p class=note>{_e(exp.description)}</p>\n"
                        f'<img alt="{_e(exp.name)}: measured and simulated {_e(c.output)}" '
                        f'src="data:image/png;base64,{_png(fig)}">')
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    body = [f"<h1>Validation of the calibrated model: {_e(', '.join(e.name for e in problem.experiments))}</h1>",
            f"<p class=note>Archive <code>{_e(str(run.path))}</code>; method {_e(run.result.method)}, "
            f"best fitness {run.result.fun:.4g} after {run.result.nfev} simulations; "
            f"written {when} by rapid-cosim {__version__}.</p>",
            "<h2>Parameters</h2>", _parameter_table(run, x, unc, interval_note),
            "<h2>Error metrics per experiment</h2>", _metrics_table(rows),
            "<p class=note>RMSE and peak error of the residual; settled change: from the pre-event level to "
            "the mean of the last 10 % before the next event; response time: from the event to 90 % of the "
            "settled change (1 s moving mean; blank when the change is under five noise levels). "
            "Simulations include the profiled transducer offset.</p>",
            "<h2>Measured and simulated</h2>", *sections]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("<!DOCTYPE html>\n<html lang=en>\n<head><meta charset=utf-8>"
                   f"<title>rapid-cosim validation: {_e(run.path.name)}</title><style>{STYLE}</style></head>\n"
                   "<body>\n" + "\n".join(body) + "\n</body>\n</html>\n", encoding="utf-8")
    return ValidationPage(out, tuple(rows), len(sections))


def _parameter_table(run: ArchivedRun, x, unc: Uncertainty | None, note: str) -> str:
    space = run.inputs.problem.space
    level = f"{100 * unc.level:.0f} % interval" if unc is not None else "interval"
    head = f"<tr><th>parameter</th><th>label</th><th>estimate</th><th>{level}</th><th>searched</th></tr>"
    rows = []
    for k, (name, label) in enumerate(zip(run.inputs.problem.names, run.inputs.problem.labels)):
        interval = "—" if unc is None else f"{unc.interval[k, 0]:.4g} … {unc.interval[k, 1]:.4g}"
        rows.append(f"<tr><td><code>{_e(name)}</code></td><td>{_e(label)}</td><td>{x[k]:.5g}</td>"
                    f"<td>{interval}</td><td>{space.lower[k]:g} … {space.upper[k]:g}</td></tr>")
    source = (f"Intervals: {unc.method} ({_e(note)})." if unc is not None and note
              else f"Intervals: {unc.method}." if unc is not None else "No interval: " + _e(note or "none given."))
    return f"<table>{head}{''.join(rows)}</table>\n<p class=note>{source}</p>"


def _metrics_table(rows: Sequence[ValidationMetrics]) -> str:
    head = ("<tr><th>experiment</th><th>output</th><th>RMSE</th><th>noise</th><th>peak error</th>"
            "<th>settled change<br>measured</th><th>simulated</th><th>error</th>"
            "<th>response time<br>measured (s)</th><th>simulated (s)</th><th>error (s)</th></tr>")
    body = []
    for m in rows:
        rel = (f" ({100 * m.settled_error / m.settled_change[0]:+.1f} %)"
               if m.settled_change[0] and np.isfinite(m.settled_change[0]) else "")
        body.append(f"<tr><td>{_e(m.experiment)}</td><td>{_e(m.output)}</td><td>{m.rmse:.3g}</td>"
                    f"<td>{_num(m.noise)}</td><td>{m.peak_error:.3g}</td><td>{m.settled_change[0]:.4g}</td>"
                    f"<td>{m.settled_change[1]:.4g}</td><td>{m.settled_error:+.3g}{rel}</td>"
                    f"<td>{_num(m.response_time[0])}</td><td>{_num(m.response_time[1])}</td>"
                    f"<td>{_num(m.response_time_error, sign=True)}</td></tr>")
    return f"<table>{head}{''.join(body)}</table>"


def _num(v, sign: bool = False) -> str:
    if v is None or not np.isfinite(v):
        return "—"
    return f"{v:+.3g}" if sign else f"{v:.3g}"


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _e(text: str) -> str:
    return html.escape(str(text), quote=True)
