"""The validation page's style sheets and the small helpers every section uses (escaping,
numbers, embedded figures, pass/fail marks).

The print style sheet is what the PDF is: A4, table headers repeated on each page, no
row, record or figure split across pages, a heading kept with what follows it, and the
pass/fail colours printed (browsers drop backgrounds when printing unless told)."""

from __future__ import annotations

import base64
import html
import io
import math

from .figures import plt

STYLE = """
body { font-family: "DejaVu Sans", system-ui, sans-serif; margin: 2em auto; max-width: 62em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 2em; border-bottom: 1px solid #ccc; }
h3 { font-size: 1.05em; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { padding: 0.2em 0.6em; border-bottom: 1px solid #e4e4e4; text-align: right; vertical-align: top; }
th:first-child, td:first-child, td.text, th.text { text-align: left; }
td:not(.text):not(:first-child), td.nowrap { white-space: nowrap; }
tr.first td { border-top: 1px solid #999; }
img { max-width: 100%; display: block; margin: 0.5em 0; }
figure { margin: 0 0 1.5em; } figcaption { font-size: 0.9em; color: #444; }
pre { background: #f5f5f5; padding: 0.5em; font-size: 0.8em; white-space: pre-wrap; word-break: break-all; }
.note { color: #555; font-size: 0.9em; }
.mark { font-weight: bold; padding: 0 0.35em; border-radius: 0.2em; white-space: nowrap; }
.mark.pass { color: #0b5a1d; background: #d8f0dc; }
.mark.fail { color: #8a1010; background: #f8d8d8; }
.mark.na { color: #666; font-weight: normal; }
.warn { color: #7a4a00; } b.bound { color: #7a4a00; font-size: 0.85em; }
code { font-size: 0.95em; }
@page { size: A4; margin: 14mm 12mm; }
@media print {
  body { max-width: none; margin: 0; font-size: 9.5pt; }
  h1, h2, h3 { break-after: avoid; page-break-after: avoid; }
  table { break-inside: auto; }
  thead { display: table-header-group; }
  tr, figure, pre, .keep { break-inside: avoid; page-break-inside: avoid; }
  img { max-height: 115mm; width: auto; }
  .mark, pre { -webkit-print-color-adjust: exact; print-color-adjust: exact; }
  section.figures { break-before: page; page-break-before: always; }
}
"""

PASS = '<span class="mark pass">&#10003; pass</span>'
FAIL = '<span class="mark fail">&#10007; fail</span>'
NOT_JUDGED = '<span class="mark na">n/a</span>'


def mark(passed: bool | None) -> str:
    return NOT_JUDGED if passed is None else PASS if passed else FAIL


def e(text) -> str:
    return html.escape(str(text), quote=True)


def num(v, sign: bool = False, digits: int = 3) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    if math.isinf(v):
        return "not settled" if v > 0 else "—"
    return f"{v:+.{digits}g}" if sign else f"{v:.{digits}g}"


def table(head: list[str], rows: list[str], cls: str = "", text: tuple[int, ...] = (0,)) -> str:
    """A table whose header repeats on every printed page (``rows`` are ``<tr>`` strings;
    the columns ``text`` hold words, their headers aligned left as the words are)."""
    ths = "".join(f"<th class=text>{h}</th>" if k in text else f"<th>{h}</th>" for k, h in enumerate(head))
    klass = f' class="{cls}"' if cls else ""
    return f"<table{klass}><thead><tr>{ths}</tr></thead><tbody>{''.join(rows)}</tbody></table>"


def png(fig) -> str:
    """``fig`` as base64 PNG (closed after), for a ``data:`` URI: the page stays one file."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")
