"""The validation page printed to PDF (and photographed) by headless Chromium.

Why Chromium: the page is the document, so the PDF is that page printed, with its print
style sheet, and nothing is laid out twice. Chromium is a system package (Debian's
``chromium``), not a Python dependency; a machine without it gets the HTML and a clear
error for the PDF. Every run uses a fresh profile and switches off Chromium's own network
traffic, so printing reaches nothing outside the machine.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from ..errors import RapidCosimError

CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
QUIET = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run", "--no-default-browser-check",
         "--hide-scrollbars")
TIMEOUT_S = 180.0


class ChromiumMissing(RapidCosimError):
    """No headless Chromium to print with."""


def chromium(executable: str | None = None) -> str:
    """The Chromium to run: ``executable``, else ``$RAPID_COSIM_CHROMIUM``, else the first
    of :data:`CANDIDATES` on the PATH."""
    wanted = executable or os.environ.get("RAPID_COSIM_CHROMIUM")
    found = shutil.which(wanted) if wanted else next(filter(None, map(shutil.which, CANDIDATES)), None)
    if found is None:
        raise ChromiumMissing(
            (f"Chromium {wanted!r} not found" if wanted else "no Chromium on the PATH (looked for "
             + ", ".join(CANDIDATES) + ")")
            + "; the PDF is printed by headless Chromium: install it (Debian/Ubuntu: apt-get install chromium) "
            "or set RAPID_COSIM_CHROMIUM; the HTML page was written all the same")
    return found


def unavailable(executable: str | None = None) -> str | None:
    """Why no PDF can be printed here (None: it can), for a caller that goes on without
    one rather than stop."""
    try:
        chromium(executable)
    except ChromiumMissing as e:
        return str(e)
    return None


def _run(args: list[str], page: Path, executable: str | None) -> None:
    exe = chromium(executable)
    with tempfile.TemporaryDirectory(prefix="rapid_cosim_chromium_") as profile:
        cmd = [exe, *QUIET, f"--user-data-dir={profile}", *args, page.resolve().as_uri()]
        try:
            done = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            raise RapidCosimError(f"Chromium did not finish printing {page} in {TIMEOUT_S:g} s") from None
    if done.returncode != 0:
        raise RapidCosimError(f"Chromium failed on {page} (exit {done.returncode}): {done.stderr.strip()[-800:]}")


def print_pdf(page: str | Path, out: str | Path, *, executable: str | None = None) -> Path:
    """``page`` (an HTML file) printed to ``out`` as Chromium prints it (A4, the page's
    print style sheet, no browser header or footer)."""
    page, out = Path(page), Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        out.unlink()  # so that a failed print cannot leave an old PDF looking new
    # no browser header or footer: the first flag for Chromium 120 on, the second before it
    _run(["--no-pdf-header-footer", "--print-to-pdf-no-header", f"--print-to-pdf={out.resolve()}"], page, executable)
    if not out.exists() or out.read_bytes()[:5] != b"%PDF-":
        raise RapidCosimError(f"Chromium wrote no PDF for {page} (expected {out})")
    return out


def screenshot(page: str | Path, out: str | Path, *, width: int = 1100, height: int = 1400,
               executable: str | None = None) -> Path:
    """A PNG of the top of ``page`` at ``width`` x ``height`` CSS pixels (for the README)."""
    page, out = Path(page), Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    _run([f"--window-size={width},{height}", f"--screenshot={out.resolve()}"], page, executable)
    if not out.exists():
        raise RapidCosimError(f"Chromium wrote no screenshot for {page}")
    return out
