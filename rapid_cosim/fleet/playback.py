"""A record played back on a unit's recordings and judged against the tolerance bands:
the check every unit's record on file gets before anything is fitted (NERC MOD-033's
comparison of the system model with an actual event, one unit at a time).

The record's model is the unit's structure of that name, with every value the record
carries in place of the structure's (the operating point and the smooth limits'
sharpness stay the test's and the bench's, as in a grid simulator). Each of the unit's
recordings (training and held-out alike: nothing is fitted here) is simulated on the
recorded frequency, its meter offset profiled as in the fitness, and its error metrics
judged (:mod:`rapid_cosim.report.validation`, :mod:`rapid_cosim.report.tolerances`).
The record passes when no judged metric fails on any recording.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ..calibration import inputs_from_experiments
from ..diagnose.selection import noise_floors
from ..structures.select import Structure, on_structure
from ..errors import ConfigError
from ..exchange import Record
from ..noise import campaign_noise
from ..report.archives import curves_at
from ..report.tolerances import Tolerances, judge, verdict
from ..report.validation import metrics


@dataclass
class Playback:
    """A record on a unit's recordings: per test, whether it passes, the metrics that
    fail, and its RMSE over the recorder's noise."""

    model: str
    source: str
    values: dict[str, float]
    passed: bool
    tests: dict[str, dict]

    @property
    def failing(self) -> list[str]:
        return [t for t, r in self.tests.items() if not r["passed"]]

    def to_json(self) -> dict:
        return asdict(self)


def structure_for(model: str, structures: list[Path]) -> Structure:
    """The unit's structure file for a record's model."""
    for path in structures:
        s = Structure.load(path)
        if s.name == model:
            return s
    names = ", ".join(Structure.load(p).name for p in structures)
    raise ConfigError(f"the record on file is {model}, and the unit's structures ({names}) have no {model}: add "
                      f"its structure file to [structures] files")


def play_back(record: Record, experiments: list, structures: list[Path], tolerances: Tolerances, *,
              package, fmu_dir, noise_fits: dict | None = None) -> Playback:
    """``record`` (iGrGen values of its model) on ``experiments`` (module docstring)."""
    structure = structure_for(record.model, structures)
    values = {f"gov.{k}": v for k, v in record.values.items()}
    kept = {k: v for k, v in values.items() if k not in structure.estimate}
    as_read = replace(structure, fixed={**structure.fixed, **kept}, optional={})
    noise_fits = noise_fits or campaign_noise(experiments)
    floors = noise_floors(experiments, noise_fits)
    inputs = inputs_from_experiments(on_structure(as_read, experiments, noise_fits), package=package,
                                     fmu_dir=fmu_dir)
    x = np.array([values.get(n, structure.estimate[n].get("start", 0.5 * (structure.estimate[n]["min"]
                                                                         + structure.estimate[n]["max"])))
                  for n in inputs.problem.names])
    tests = {}
    for i, exp in enumerate(inputs.problem.experiments):
        m = metrics(curves_at(inputs, x, i))
        checks = judge(m, tolerances)
        failing = [c.metric for c in checks if c.passed is False]
        tests[exp.name] = {"passed": verdict(checks) is not False, "failing": failing,
                           "rmse_over_noise": float(m.rmse / floors[exp.name].sigma)}
    return Playback(record.model, record.file, dict(record.values), all(t["passed"] for t in tests.values()), tests)
