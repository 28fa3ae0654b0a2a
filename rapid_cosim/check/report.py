"""The checks of a config, a unit and a fleet, and the report they give: every problem
located, what was loaded, what the run will do and about what it costs."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from ..compiler.source import ModelSource
from ..errors import Finding, RapidCosimError, finding
from ..exchange import SUPPORTED
from ..experiment.schema import explain
from .cost import PLAYBACK_EXTRA, duration, identify_simulations, method_simulations, seconds_per_simulation


@dataclass
class CheckReport:
    """What ``rapid-cosim check`` found: ``problems`` (each located), the ``lines`` it
    says about what was loaded and what the run will do, and the run's cost."""

    path: str
    kind: str  # config, unit or fleet
    problems: list[Finding] = field(default_factory=list)
    lines: list[str] = field(default_factory=list)
    simulations: int = 0
    seconds: float = 0.0  # about, on this machine

    @property
    def ok(self) -> bool:
        return not self.problems

    def text(self) -> str:
        out = [f"{self.path} ({self.kind}): " + ("ok" if self.ok else f"{len(self.problems)} problem(s)")]
        out += [f"  {line}" for line in self.lines]
        if self.simulations:
            took = duration(self.seconds)
            out.append(f"  about {self.simulations:,} simulations: {'about ' if took[0].isdigit() else ''}{took} of "
                       "simulation on this machine in one process (counts are rough: the methods stop when they "
                       "converge)")
        for p in self.problems:
            words = explain(p.where) if p.where and not p.where.startswith(("row ", "line ", "--")) else None
            out.append(f"  problem: {p}" + (f" (the key: {words})" if words else ""))
        return "\n".join(out)


def _estimates(exp) -> str:
    return ", ".join(f"{s.label} [{s.min:g}, {s.max:g}]" + (" log" if s.scale == "log" else "")
                     for s in exp.estimate) or "nothing"


def _cost(report: CheckReport, experiments: Sequence, simulations: int, source: ModelSource) -> None:
    try:
        per = seconds_per_simulation(experiments, source=source)
    except RapidCosimError as e:
        report.problems.append(finding(e))
        return
    report.simulations, report.seconds = simulations, simulations * per
    report.lines.append(f"one simulation of every test: {1e3 * per:.2g} ms on this machine (batched)")


def check_configs(paths: Sequence[Path], *, method: str, source: ModelSource = ModelSource()) -> CheckReport:
    """Configs as ``rapid-cosim estimate`` loads them, jointly fitted by ``method``."""
    from ..calibration import inputs_from_experiments
    from ..estimators.chain import parse_method
    from ..experiment.problems import every_problem
    from ..identify.check import quietly

    report = CheckReport(", ".join(map(str, paths)), "config")
    try:  # the method first: a misspelt one is said before any model is built
        stages = parse_method(method)
    except ValueError as e:
        stages = None
        report.problems.append(Finding(None, "--method", str(e)))
    notes: list[str] = []
    experiments = []
    for path in paths:
        exp, problems = quietly(lambda: every_problem(path), notes)
        experiments += [exp] if exp is not None else []
        report.problems += [finding(e) for e in problems]
    if not experiments:
        return report
    try:
        inputs = inputs_from_experiments(experiments, source=source)
    except RapidCosimError as e:
        report.problems.append(finding(e))
        return report
    for exp in experiments:
        report.lines += [f"{exp.name}: {line}" for line in exp.recording.lines()]
        report.lines.append(f"{exp.name}: {exp.model}, estimates {_estimates(exp)}")
    if stages is None:
        return report
    report.lines.append("stages: " + " then ".join(f"{s.name}" + (f" ({s.max_iter} iterations)" if s.max_iter else "")
                                                 for s in stages) + f" on {inputs.problem.space.dim} parameters")
    _cost(report, experiments, method_simulations(method, inputs.problem.space.dim), source)
    return report


def _unit_lines(checked, report: CheckReport) -> None:
    from ..diagnose.catalogue import CATALOGUE
    from ..identify.unit import NO_HOLDOUT

    unit = checked.unit
    held = set(unit.holdout)
    for exp in checked.experiments:
        report.lines += [f"{exp.name}{' (held out)' if exp.name in held else ''}: {line}"
                         for line in exp.recording.lines()]
    if not held:
        report.lines.append(f"warning: {NO_HOLDOUT}")
    report.lines.append(f"explanation: TG Type I and the effect catalogue ({len(CATALOGUE)} effects: "
                        f"{', '.join(CATALOGUE)}), then pairs with the best")
    for s in checked.structures:
        optional = "".join(f"; with {', '.join(k.removeprefix('gov.') for k in s.parts(e))} free too ({e})"
                           for e in s.effects)
        report.lines.append(f"structure {s.name}: estimates {', '.join(k.removeprefix('gov.') for k in s.estimate)}"
                            f"{optional}")


def check_unit_report(path: Path, *, source: ModelSource = ModelSource()) -> CheckReport:
    """A unit as ``rapid-cosim identify`` loads it."""
    from ..diagnose.catalogue import CATALOGUE
    from ..identify.check import check_unit

    checked = check_unit(path, source=source)
    report = CheckReport(str(path), "unit", list(checked.findings))
    if checked.unit is None:
        return report
    _unit_lines(checked, report)
    if checked.ok:
        fits = sum(1 + len(s.optional_variants()) for s in checked.structures)
        training = [e for e in checked.experiments if e.name not in checked.unit.holdout]
        _cost(report, training, identify_simulations(len(CATALOGUE), fits), source)
    return report


def check_fleet(path: Path, *, source: ModelSource = ModelSource()) -> CheckReport:
    """A fleet as ``rapid-cosim fleet`` loads it: its file, every unit and its record on file."""
    from ..diagnose.catalogue import CATALOGUE
    from ..fleet.check import check_entry
    from ..fleet.spec import load_fleet

    report = CheckReport(str(path), "fleet")
    try:
        spec = load_fleet(path)
    except RapidCosimError as e:
        report.problems.append(finding(e))
        return report
    per_unit, playback = [], 0
    for entry in spec.units:
        checked = check_entry(entry, source=source)
        report.problems += checked.problems
        if not checked.ok:
            report.lines.append(f"{entry.name}: {len(checked.problems)} problem(s)")
            continue
        tests = checked.unit.experiments
        if checked.unsupported:
            report.lines.append(f"{entry.name}: record on file is {checked.unsupported}: not supported (listed, not "
                                f"checked; the models read: {SUPPORTED})")
            continue
        record = (f"record on file {checked.record.model} ({Path(checked.record.file).name}, line "
                  f"{checked.record.line})" if checked.record else "no record on file: identified")
        report.lines.append(f"{entry.name}: {len(tests)} test(s), {record}"
                            + ("" if all(e.recording.plain for e in tests) else
                               "; " + "; ".join(line for e in tests for line in e.recording.lines()
                                                if not line.startswith("time base") or "regular" not in line)))
        fits = sum(1 + len(s.optional_variants()) for s in checked.unit.structures)
        dim = max((len(s.estimate) for s in checked.unit.structures), default=1)
        playback += PLAYBACK_EXTRA * (dim + 1)
        per_unit.append((tests, identify_simulations(len(CATALOGUE), fits)))
    if per_unit:
        tests, each = per_unit[0]
        try:
            per = seconds_per_simulation(tests, source=source)
        except RapidCosimError as e:
            report.problems.append(finding(e))
            return report
        report.simulations = playback + sum(n for _, n in per_unit)
        report.seconds = report.simulations * per
        report.lines.append(f"checking every record on file: about {playback:,} simulations; identifying a unit "
                            f"whose record fails: about {each:,} ({duration(each * per)} each on one worker); the "
                            "total below is for every unit identified")
    return report
