"""Progress an engineer reads (issue 56): no carriage-return frames in a file, a line at
the start, at most one every few seconds, and one at the end; a stage without a known
length counts instead of jumping."""

from __future__ import annotations

import io

from rapid_cosim.progress import Stage


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_in_a_log_a_stage_writes_plain_lines_and_no_frames():
    out = io.StringIO()
    stage = Stage("pf", 10, stream=out, every=3600.0)
    for k in range(10):
        stage.update(1, f"best {1.0 / (k + 1):.3g}")
    stage.close()
    lines = out.getvalue().splitlines()
    assert "\r" not in out.getvalue()
    assert lines[0] == "pf: started, 10 it" and lines[-1].startswith("pf: done, 10 of 10 it, best 0.1 in ")
    assert len(lines) == 2  # nothing between: the interval had not passed


def test_in_a_log_a_long_stage_says_where_it_is_at_its_interval():
    out = io.StringIO()
    stage = Stage("nm", None, stream=out, every=0.0)  # counted: Nelder-Mead stops when it converges
    stage.update(1, "best 2")
    stage.update(1, "best 1")
    stage.close()
    assert out.getvalue().splitlines() == ["nm: started", "nm: 1 it, best 2", "nm: 2 it, best 1",
                                           out.getvalue().splitlines()[-1]]
    assert out.getvalue().splitlines()[-1].startswith("nm: done, 2 it, best 1 in ")


def test_on_a_terminal_it_is_a_bar_and_disabled_it_is_silent():
    term = _Terminal()
    with Stage("units", 3, unit="unit", stream=term) as stage:
        stage.update(3)
    assert "units" in term.getvalue() and "3/3" in term.getvalue()
    quiet = io.StringIO()
    with Stage("units", 3, stream=quiet, enabled=False) as stage:
        stage.update(3)
    assert quiet.getvalue() == ""


def test_identifys_log_passes_its_lines_in_a_log_and_counts_fits_per_stage():
    from rapid_cosim.progress import StagedLog

    out = io.StringIO()
    log = StagedLog(stream=out, every=3600.0)
    for line in ("identifying u: 2 training and 1 held-out experiments", "the explanation (TG Type I):",
                 "  fitting none ...", "    none: fitness 1.2, BIC 40.1, 90 simulations",
                 "    deadband: fitness 1.0, BIC 20.3, 120 simulations", "the standard records:",
                 "  TGOV1 (R, T1): BIC 12.0, variance ratio 1.01"):
        log(line)
    log.close()
    lines = out.getvalue().splitlines()
    assert "\r" not in out.getvalue()
    assert lines[:5] == ["identifying u: 2 training and 1 held-out experiments", "the explanation (TG Type I):",
                         "  fitting none ...", "    none: fitness 1.2, BIC 40.1, 90 simulations",
                         "    deadband: fitness 1.0, BIC 20.3, 120 simulations"]
    assert lines[5].startswith("the explanation (TG Type I): done, 2 fit, deadband in ")
    assert lines[6] == "the standard records:" and lines[8].startswith("the standard records: done, 1 fit, ")


def test_identifys_log_on_a_terminal_writes_lines_above_a_bar():
    from rapid_cosim.progress import StagedLog

    term = _Terminal()
    log = StagedLog(stream=term)
    log("the explanation (TG Type I):")
    log("    none: fitness 1.2, BIC 40.1, 90 simulations")
    log.close()
    text = term.getvalue()
    assert "    none: fitness 1.2, BIC 40.1, 90 simulations\n" in text and "the explanation (TG Type I)" in text
