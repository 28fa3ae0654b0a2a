"""Table 1 of the paper from the archives alone: per test and method, R, Ts and the
fitness (the RSSD of Algorithm 1, line 14, with the transducer offset profiled out),
plus the simulations used and the wall time of the run."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..archive import RunArchive
from ..errors import ArchiveError


@dataclass(frozen=True)
class Row:
    test: str
    method: str
    R: float
    Ts: float
    fitness: float
    nfev: int
    wall_time: float
    archive: str


def read_row(test: str, method: str, archive: str | Path) -> Row:
    """One row from a finished archive (reads the stored result only: no simulation)."""
    archive = Path(archive)
    if not archive.exists():
        raise ArchiveError(f"{archive}: no such archive (run 'make {test}' or 'rapid-cosim staged-test "
                           f"experiments/{test}' first)")
    with RunArchive(archive) as view:
        result = view.result()
        if result is None:
            raise ArchiveError(f"{archive}: the run is {view.status}, not finished")
        best = dict(zip(view.names, result.x))
    try:
        r, ts = best["gov.R"], best["gov.Ts"]
    except KeyError:
        raise ArchiveError(f"{archive}: the run does not estimate gov.R and gov.Ts "
                           f"(it estimates {', '.join(best)})") from None
    return Row(test, method, float(r), float(ts), float(result.fun), int(result.nfev),
               float(result.wall_time), str(archive))


HEADER = ("test", "method", "R", "Ts (s)", "fitness", "simulations", "wall time (s)")


def _cells(row: Row) -> tuple[str, ...]:
    return (row.test, row.method, f"{row.R:.4f}", f"{row.Ts:.4f}", f"{row.fitness:.4e}", str(row.nfev),
            f"{row.wall_time:.1f}")


def markdown(rows: Sequence[Row]) -> str:
    """The table as GitHub Markdown; the test is named on its first row only, as in the paper."""
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "|".join(["---"] * 2 + ["---:"] * 5) + "|"]
    previous = None
    for row in rows:
        cells = list(_cells(row))
        if row.test == previous:
            cells[0] = ""
        previous = row.test
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def text(rows: Sequence[Row]) -> str:
    """Plain aligned text for the terminal."""
    table = [HEADER] + [_cells(r) for r in rows]
    widths = [max(len(r[k]) for r in table) for k in range(len(HEADER))]
    out = []
    for j, r in enumerate(table):
        out.append("  ".join(c.ljust(w) if k < 2 else c.rjust(w) for k, (c, w) in enumerate(zip(r, widths))))
        if j == 0:
            out.append("  ".join("-" * w for w in widths))
    return "\n".join(out) + "\n"


def csv_text(rows: Sequence[Row]) -> str:
    """Full precision, machine-readable: numbers as Python writes them (repr round-trips)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["test", "method", "R", "Ts", "fitness", "nfev", "wall_time", "archive"])
    for r in rows:
        w.writerow([r.test, r.method, repr(r.R), repr(r.Ts), repr(r.fitness), r.nfev, repr(r.wall_time), r.archive])
    return buf.getvalue()


def write_table1(rows: Sequence[Row], out_dir: str | Path, stem: str = "table1") -> tuple[Path, Path]:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    md, cs = out_dir / f"{stem}.md", out_dir / f"{stem}.csv"
    md.write_text(markdown(rows))
    cs.write_text(csv_text(rows))
    return md, cs
