"""Tolerance bands of the validation report: each metric of :mod:`.metrics` passes or
fails against a band, and the bands are configurable.

A band is the **largest** of the terms it is given (a term that cannot be evaluated,
such as ``noise`` for a test without a noise level, is left out; a band with no term
left judges nothing, shown as "n/a"):

``relative``
    a share of the measured quantity (the settled change for RMSE; the measured peak
    change, settled change or time for the others);
``noise``
    a multiple of the test's noise level (pu): a model can be asked to be no better
    than the recording;
``absolute``
    pu of the compared output;
``seconds``
    for the three times.

Where the defaults come from
----------------------------
NERC MOD-027-1 (R2) asks the Generator Owner to verify the turbine-governor model by
comparing its simulated active power response with the unit's recorded response to a
frequency excursion or a governor reference change; it names what is compared but sets
no numerical band. AEMO's *Power System Model Guidelines* (section 6, "Model accuracy
requirements") state numerical accuracy requirements on the same kind of measures (rise
time, settling time, peak and steady-state values); their numbers could not be checked
against the published text when this was written, so none is quoted or copied here.
**Every default below is therefore this project's own choice**, stated with its reason;
a grid operator's own bands go in a tolerance file (``rapid-cosim report --tolerances``).

* ``rmse``: 2 noise levels or 5 % of the settled change. A model that leaves only the
  recorder's noise has RMSE near one noise level; correlated noise, the profiled offset
  and a held-out prediction raise it, so twice is the first sign of a model error, and
  5 % of the change keeps a large step from being judged on a very quiet recorder alone.
* ``peak_change`` and ``settled_change``: 10 % of the measured change or 3 noise levels.
  10 % is the share commonly asked of a steady-state and a peak in model-validation
  practice; 3 noise levels keep a small change from failing on noise.
* ``rise_time`` and ``time_to_peak``: 10 % of the measured time or 1 s (the 1 s of
  smoothing that the times are read through).
* ``settling_time``: 20 % of the measured time or 2 s: settling is read where a slow
  tail crosses a narrow band, so it scatters about twice as much as the rise time.

File format (a ``[validation]`` table, on its own or in a larger TOML file)::

    [validation]
    rmse = { noise = 2.0, relative = 0.05 }
    settled_change = { relative = 0.05 }          # stricter: 5 % only
    settling_time = { relative = 0.2, seconds = 3.0 }

A metric not named keeps its default; ``metric = {}`` judges nothing for it.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

from ..errors import ConfigError
from ..experiment.reader import load_toml
from ..experiment.schema import METRIC_TERMS
from .metrics import ValidationMetrics

# METRIC_TERMS (each metric's terms) lives in experiment.schema, with every key docs/config.md lists.
# term -> (lowest, highest) accepted value: a band of zero would fail every model, and a
# share above 1 or a thousand noise levels would pass any.
TERM_RANGES: dict[str, tuple[float, float]] = {"relative": (0.0, 1.0), "noise": (0.0, 100.0),
                                               "absolute": (0.0, 10.0), "seconds": (0.0, 600.0)}
LABELS = {"rmse": "RMSE", "peak_change": "peak change", "settled_change": "settled change",
          "rise_time": "rise time (90 %)", "time_to_peak": "time to peak", "settling_time": "settling time"}
DEFAULT_BANDS: dict[str, dict[str, float]] = {
    "rmse": {"noise": 2.0, "relative": 0.05},
    "peak_change": {"relative": 0.10, "noise": 3.0},
    "settled_change": {"relative": 0.10, "noise": 3.0},
    "rise_time": {"relative": 0.10, "seconds": 1.0},
    "time_to_peak": {"relative": 0.10, "seconds": 1.0},
    "settling_time": {"relative": 0.20, "seconds": 2.0},
}
# Each default's reason, shown beside it on the page (the module docstring says the same).
DEFAULT_REASONS: dict[str, str] = {
    "rmse": "a model that leaves only the recorder's noise has an RMSE near one noise level; correlated noise, "
            "the profiled offset and held-out prediction raise it, so twice is the first sign of a model error; "
            "5 % of the change keeps a large step from being judged on a very quiet recorder alone",
    "peak_change": "10 % is the share commonly asked of a peak and a steady state; 3 noise levels keep a small "
                   "change from failing on noise",
    "settled_change": "as the peak change",
    "rise_time": "10 % of the time, or the 1 s of smoothing the times are read through",
    "time_to_peak": "as the rise time",
    "settling_time": "settling is read where a slow tail crosses a narrow band, so it scatters about twice as "
                     "much as the rise time",
}
# What a failed band means for someone who will use the record, per metric (the page's
# "What the failures mean"): which part of the model sets it, and which studies it touches.
FAILURE_MEANINGS: dict[str, tuple[str, str]] = {  # (larger, smaller): simulated above / below measured
    "rmse": ("the simulated response is further from the measurement than the recorder's noise explains: the "
             "model misses part of the response (the figure shows where); every study that uses the record "
             "inherits that miss", ""),
    "peak_change": ("the model's largest excursion is larger than the unit's: its gain or fast lags overstate "
                    "the first seconds' response; a frequency nadir study with this record is optimistic",
                    "the model's largest excursion is smaller than the unit's: its gain or fast lags understate "
                    "the first seconds' response; a frequency nadir study with this record is pessimistic"),
    "settled_change": ("the model settles at a larger change than the unit: its droop is too small (or a limit "
                       "is missing); steady-state sharing with this record overstates the unit's part",
                       "the model settles at a smaller change than the unit: its droop is too large (or a limit "
                       "binds that should not); steady-state sharing with this record understates the unit's part"),
    "rise_time": ("the model reaches 90 % of its change later than the unit: its time constants are too slow "
                  "for this test (or a slow tail moves the 90 % point); how fast the unit supports the "
                  "frequency is understated",
                  "the model reaches 90 % of its change sooner than the unit: its time constants are too fast "
                  "for this test (or a slow tail moves the 90 % point); how fast the unit supports the "
                  "frequency is overstated"),
    "time_to_peak": ("the model peaks later than the unit: its lags are too slow",
                     "the model peaks sooner than the unit: its lags are too fast"),
    "settling_time": ("the model takes longer to settle than the unit: a slow mode (the reheater, the water "
                      "column) is too slow or too large",
                      "the model settles sooner than the unit: a slow mode is too fast or missing"),
}


def failure_meaning(check: Check) -> str:
    """The words of :data:`FAILURE_MEANINGS` for a failed check, by the sign of its error."""
    larger, smaller = FAILURE_MEANINGS[check.metric]
    return smaller if smaller and check.error is not None and check.error < 0 else larger


SOURCE_NOTE = ("NERC MOD-027-1 (R2) asks that the model's simulated active power response be compared with the "
               "unit's recorded response to a frequency excursion or a governor reference change, and sets no "
               "numerical band; AEMO's Power System Model Guidelines (section 6, model accuracy requirements) state "
               "numerical requirements on the same kind of measures, whose numbers could not be checked against the "
               "published text here, so none is quoted. The default bands are therefore the project's own choice, "
               "each with its reason; a grid operator's bands go in a tolerance file (--tolerances).")
DEFAULT_SOURCE = "the project's own defaults (NERC MOD-027-1 sets no numerical band)"


@dataclass(frozen=True)
class Tolerances:
    """The band of every metric (term -> value) and where they come from."""

    bands: Mapping[str, Mapping[str, float]] = field(default_factory=lambda: DEFAULT_BANDS)
    source: str = DEFAULT_SOURCE

    def reason(self, metric: str) -> str:
        """Why the band is what it is: the default's reason, or the file it came from."""
        if dict(self.bands.get(metric, {})) == DEFAULT_BANDS[metric]:
            return "default: " + DEFAULT_REASONS[metric]
        return f"from {self.source.split(' (')[0]}"

    def describe(self, metric: str) -> str:
        terms = self.bands.get(metric, {})
        if not terms:
            return "not judged"
        of = "the measured settled change" if metric == "rmse" else "measured"
        words = {"relative": lambda v: f"{100 * v:g} % of {of}", "noise": lambda v: f"{v:g} noise levels",
                 "absolute": lambda v: f"{v:g} pu", "seconds": lambda v: f"{v:g} s"}
        return "the larger of " + " and ".join(words[k](v) for k, v in terms.items()) if len(terms) > 1 \
            else words[next(iter(terms))](next(iter(terms.values())))


@dataclass(frozen=True)
class Check:
    """One metric of one test against its band: ``passed`` None when not judged."""

    metric: str
    measured: float | None
    simulated: float | None
    error: float | None
    band: float | None
    passed: bool | None


def load_tolerances(path: str | Path) -> Tolerances:
    """The ``[validation]`` table of ``path`` over the defaults; a bad file is refused with
    the file, line, key, value and the allowed range."""
    path = Path(path)
    if not path.exists():
        raise ConfigError("no such tolerance file", str(path))
    doc, text = load_toml(path, "the tolerance file")
    table = doc.get("validation")
    if not isinstance(table, dict):
        raise ConfigError("no [validation] table (metrics: " + ", ".join(METRIC_TERMS) + ")", str(path))
    bands = {k: dict(v) for k, v in DEFAULT_BANDS.items()}
    for metric, terms in table.items():
        where = f"{path}:{_line(text, metric)}"
        if metric not in METRIC_TERMS:
            raise ConfigError(f"unknown metric {metric!r}; allowed: {', '.join(METRIC_TERMS)}", where,
                              f"validation.{metric}")
        if not isinstance(terms, dict):
            raise ConfigError(f"{metric} = {terms!r}: give a table of terms, e.g. "
                              f"{{ {METRIC_TERMS[metric][0]} = 0.1 }}", where, f"validation.{metric}")
        bands[metric] = {}
        for term, value in terms.items():
            key = f"validation.{metric}.{term}"
            where = f"{path}:{_line(text, term, after=metric)}"
            if term not in METRIC_TERMS[metric]:
                raise ConfigError(f"unknown term {term!r} for {metric}; allowed: {', '.join(METRIC_TERMS[metric])}",
                                  where, key)
            lo, hi = TERM_RANGES[term]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or not lo < value <= hi:
                raise ConfigError(f"{term} = {value!r} is outside the allowed range: a number > {lo:g} and "
                                  f"<= {hi:g}", where, key)
            bands[metric][term] = float(value)
    return Tolerances(bands, f"{path} (metrics not named there: {DEFAULT_SOURCE})")


def _line(text: str, key: str, after: str | None = None) -> int:
    """1-based line where ``key`` is set or its ``[validation.key]`` table opens (looking
    from where ``after`` is), for the error message."""
    lines = text.splitlines()

    def setting(name: str):
        n = re.escape(name)
        return re.compile(rf"^\s*\[\s*validation\.{n}\s*\]|(^|[\s{{,])\"?{n}\"?\s*=")

    start = 0 if after is None else next((i for i, s in enumerate(lines) if setting(after).search(s)), 0)
    return next((i + 1 for i in range(start, len(lines)) if setting(key).search(lines[i])), start + 1)


def judge(m: ValidationMetrics, tol: Tolerances) -> tuple[Check, ...]:
    """Every metric of ``m`` against its band, in :data:`METRIC_TERMS` order."""
    values = {"rmse": (None, None, m.rmse), "peak_change": (*m.peak_change, m.peak_change_error),
              "settled_change": (*m.settled_change, m.settled_error),
              "rise_time": (*m.rise_time, m.rise_time_error),
              "time_to_peak": (*m.time_to_peak, m.time_to_peak_error),
              "settling_time": (*m.settling_time, m.settling_time_error)}
    checks = []
    for metric in METRIC_TERMS:
        measured, simulated, error = values[metric]
        scale = abs(m.settled_change[0]) if metric == "rmse" else measured
        band = _band(tol.bands.get(metric, {}), scale, m.noise)
        passed = None if band is None or error is None or math.isnan(error) else abs(error) <= band
        checks.append(Check(metric, measured, simulated, error, band, passed))
    return tuple(checks)


def _band(terms: Mapping[str, float], measured: float | None, noise: float | None) -> float | None:
    found = []
    for term, v in terms.items():
        if term == "relative" and measured is not None and math.isfinite(measured):
            found.append(v * abs(measured))
        elif term == "noise" and noise is not None and math.isfinite(noise):
            found.append(v * noise)
        elif term in ("absolute", "seconds"):
            found.append(v)
    return max(found) if found else None


def verdict(checks: tuple[Check, ...]) -> bool | None:
    """A test passes when every judged metric does (None: nothing judged)."""
    judged = [c.passed for c in checks if c.passed is not None]
    return None if not judged else all(judged)
