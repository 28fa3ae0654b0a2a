"""A unit checked before anything is fitted: the unit file, every recording its configs
read, every structure file against its benches, the held-out names.

Why every problem at once: an identification takes minutes, and a user mending a unit
folder wants the whole list, each problem naming the file and its key or row, not one
error per attempt. ``rapid-cosim check`` prints it; :func:`rapid_cosim.identify.identify`
stops on it before the first fit. What reading a recording warned of (masked frames,
repaired stamps) is kept as notes, each said once.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

from ..compiler.source import ModelSource
from ..data import close_matches
from ..data.csv_table import SkippedRowWarning
from ..data.measured import MaskedSamplesWarning
from ..data.timebase import TimeBaseWarning
from ..errors import Finding, RapidCosimError, finding
from ..experiment import Experiment
from ..experiment.problems import every_problem
from ..experiment.recording import RecordingWarning
from ..structures.structure import Structure
from .unit import Unit

# what reading a recording warns of, each also a line of the experiment's Recording
_RECORDING_FACTS = (MaskedSamplesWarning, SkippedRowWarning, TimeBaseWarning, RecordingWarning)


@dataclass
class UnitCheck:
    """What a unit's run would load, and every problem found in it."""

    unit: Unit | None
    experiments: list[Experiment] = field(default_factory=list)
    structures: list[Structure] = field(default_factory=list)
    findings: list[Finding] = field(default_factory=list)
    notes: list[warnings.WarningMessage] = field(default_factory=list)  # the recordings' warnings, once each

    @property
    def ok(self) -> bool:
        return not self.findings


def quietly(load, notes: list[warnings.WarningMessage]):
    """``load()`` with its warnings kept in ``notes`` (each text once) instead of shown:
    the caller says them once (:func:`say`), or reports them otherwise."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = load()
    seen = {str(w.message) for w in notes}
    for w in caught:
        if str(w.message) not in seen:
            seen.add(str(w.message))
            notes.append(w)
    return out


def unsaid(notes: list[warnings.WarningMessage], experiments) -> list[warnings.WarningMessage]:
    """The notes that the experiments' recording lines do not say already: what reading
    found in a recording (a units row skipped, samples masked, stamps repaired) is a line
    of its :class:`~rapid_cosim.experiment.recording.Recording`, printed with the others,
    so it is not warned of as well."""
    sources = {str(d.source) for e in experiments for d in (e.data, *e.files.values())}
    return [w for w in notes if not (issubclass(w.category, _RECORDING_FACTS)
                                     and any(str(w.message).startswith(f"{s}: ") for s in sources))]


def say(notes: list[warnings.WarningMessage]) -> None:
    """Warn of each note again, as it was raised: shown once by whatever filter is on (the
    CLI's says each text once, with how often it recurred)."""
    for w in notes:
        warnings.warn(w.message if isinstance(w.message, Warning) else str(w.message), w.category, stacklevel=2)


def check_unit(path: str | Path, *, source: ModelSource = ModelSource()) -> UnitCheck:
    """Load and check everything of the unit at ``path`` (a unit.toml or its folder)."""
    try:
        unit = Unit.load(path)
    except RapidCosimError as e:
        return UnitCheck(None, findings=[finding(e)])
    out = UnitCheck(unit)
    for config in unit.configs:
        exp, problems = quietly(lambda: every_problem(config), out.notes)
        out.experiments += [exp] if exp is not None else []
        out.findings += [finding(e) for e in problems]
    names = [e.name for e in out.experiments]
    loaded_all = len(out.experiments) == len(unit.configs)
    for name in unit.holdout:
        if loaded_all and name not in names:
            close = close_matches(name, names, n=1)
            out.findings.append(Finding(str(unit.path), "tests.holdout",
                                        f"{name!r} is not among the unit's experiments ({', '.join(names)})"
                                        + (f"; did you mean {close[0]!r}?" if close else "")))
    if loaded_all and unit.holdout and set(names) <= set(unit.holdout):
        out.findings.append(Finding(str(unit.path), "tests.holdout", "every experiment is held out: nothing to fit"))
    for file in unit.structures:
        try:
            structure = Structure.load(file)
        except RapidCosimError as e:
            out.findings.append(finding(e))
            continue
        out.structures.append(structure)
        found = structure.check(source=source)
        out.findings += found
        if found:
            continue
        for exp in out.experiments:  # the tests on the structure's bench, as the selection fits them
            try:
                quietly(lambda: structure.experiment(exp), out.notes)
            except RapidCosimError as e:
                out.findings.append(finding(e))
    return out
