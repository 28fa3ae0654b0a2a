"""The validation page's sections from plain data (issue 56's report items): a parameter
on a bound of its search range is flagged, and each failed band says what it means."""

from __future__ import annotations

from types import SimpleNamespace

from rapid_cosim.report.sections import failures_section, on_bound, record_section
from rapid_cosim.report.unit import DeliveredRecord, ParameterRow
from rapid_cosim.validation.tolerances import Check


def test_a_parameter_on_its_bound_is_flagged_and_said_once():
    rows = (ParameterRow("gov.T3", 3.0, "estimated", (2.956, 3.044), (3.0, 30.0), "T3"),
            ParameterRow("gov.R", 0.05, "estimated", (0.049, 0.051), (0.02, 0.12), "R"),
            ParameterRow("gov.T5", 6.0, "documented"))
    html = record_section(DeliveredRecord("TGOV1", "1 'TGOV1' ...", None, "fitted", rows), "", 0.9)
    assert html.count("on lower bound") == 1 and "T3 = 3 is on the lower bound of its search range" in html
    assert "R = 0.05 is on" not in html
    assert on_bound(29.8, (3.0, 30.0)) == "upper" and on_bound(10.0, (3.0, 30.0)) is None
    assert on_bound(0.0067, (0.001, 1.0)) is None and on_bound(0.00101, (0.001, 1.0)) == "lower"  # in the log
    assert on_bound(-0.00101, (-1.0, -0.001)) == "upper" and on_bound(-0.99, (-1.0, -0.001)) == "lower"
    assert on_bound(1.0, None) is None


def test_each_failed_band_says_what_it_means_once():
    late = Check("rise_time", 4.0, 5.3, 1.3, 0.9, False)
    small = Check("settled_change", 0.2, 0.17, -0.03, 0.02, False)
    fine = Check("rmse", None, None, 0.001, 0.002, True)
    html = failures_section([(SimpleNamespace(experiment="test1"), (late, small, fine))])
    assert html.count("<li>") == 2
    assert "reaches 90 % of its change later than the unit" in html
    assert "settles at a smaller change than the unit: its droop is too large" in html
    assert failures_section([(SimpleNamespace(experiment="test1"), (fine,))]) == ""
