"""What reports read from archives: one finished run as plain numbers, its curves at its
best point (:func:`~rapid_cosim.validation.curves.curves_at` on the archived inputs), and
the paper-style caption of a staged test. Nothing here estimates or judges."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..calibration import RunInputs, inputs_from_archive
from ..archive import RunArchive
from ..errors import ArchiveError
from ..estimators.base import EstimationResult
from ..fitting.objective import evaluate_in_detail
from ..experiment import Experiment
from ..validation.curves import FitCurves, curves_at


@dataclass(frozen=True)
class ArchivedRun:
    """A finished run: its result (history included) and the inputs rebuilt from the file."""

    path: Path
    result: EstimationResult
    inputs: RunInputs

    @property
    def experiment(self) -> Experiment:
        return self.inputs.experiments[0]

    def value(self, label: str) -> float:
        """Best value of the parameter labelled ``label`` (e.g. 'R') or named (e.g. 'gov.R')."""
        problem = self.inputs.problem
        for name, lab, v in zip(problem.names, problem.labels, self.result.x):
            if label in (name, lab):
                return float(v)
        raise KeyError(f"{self.path}: no parameter {label!r}; parameters: {', '.join(problem.labels)}")


def load_run(path: str | Path) -> ArchivedRun:
    path = Path(path)
    if not path.exists():
        raise ArchiveError(f"{path}: no such archive")
    with RunArchive(path) as view:
        result = view.result()
        if result is None:
            raise ArchiveError(f"{path}: the run is {view.status}, not finished "
                               f"('rapid-cosim resume {path}' continues it)")
        inputs = inputs_from_archive(view)
    return ArchivedRun(path, result, inputs)


def fit_curves(run: ArchivedRun, experiment: int | str = 0, x=None) -> FitCurves:
    """Simulate the archived FMU at the run's best point (or ``x``) on the archived data."""
    problem = run.inputs.problem
    i = problem.experiment_index(experiment) if isinstance(experiment, str) else experiment
    return curves_at(run.inputs, run.result.x if x is None else x, i)


def caption(exp: Experiment) -> str:
    """'Test 1 (MCR 60 %, Δf = -200 mHz)' as the paper's Figs. 3-8, plus the return if any."""
    name = exp.name
    head = f"Test {name[4:]}" if name.startswith("test") and name[4:].isdigit() else name
    parts = []
    if "gov.p_ref" in exp.fixed:
        parts.append(f"MCR {100 * exp.fixed['gov.p_ref']:.0f} %")
    if "src.df" in exp.fixed:
        parts.append(f"Δf = {1000 * exp.fixed['src.df']:+.0f} mHz")
    if "src.t_return" in exp.fixed and exp.fixed["src.t_return"] < exp.simulation.stop_time:
        parts.append(f"back to 0 at {exp.fixed['src.t_return']:g} s")
    return f"{head} ({', '.join(parts)})" if parts else head


def offsets_at(run: ArchivedRun, x) -> dict[str, tuple[float, float]]:
    """Each experiment's (profiled offset, RSSD) at ``x``: for a joint run, at its posterior mean."""
    details = evaluate_in_detail(run.inputs.problem, run.inputs.fmus, np.asarray(x, dtype=float))
    out = {}
    for d in details:
        output = next(o for o in d.experiment.outputs if d.experiment.weights[o] > 0)
        out[d.experiment.name] = (float(d.fit.offsets[output]), float(d.fit.rssd))
    return out
