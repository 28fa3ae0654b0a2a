"""A fleet's unit checked before anything is played back or fitted: the unit as
``rapid-cosim identify`` checks it (:func:`rapid_cosim.identify.check.check_unit`), and
its record on file read for its bus and machine and matched to one of its structures. A
record on file of a governor model no table reads (a planning case holds many) is noted,
not a problem: its unit is listed as not supported and the fleet goes on.

The same check runs first in each unit's job (a unit that fails it is a row listing
every problem, and nothing of it is run) and, for the whole fleet at once, in
``rapid-cosim check FLEET.toml``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..compiler.source import ModelSource
from ..errors import Finding, RapidCosimError, finding
from ..exchange import Record, UnsupportedRecord, read_record
from ..identify.check import UnitCheck, check_unit
from .spec import UnitEntry


@dataclass
class EntryCheck:
    """A fleet unit's check: the unit's, and its record on file read (None: none, or unreadable)."""

    entry: UnitEntry
    unit: UnitCheck
    record: Record | None = None
    findings: list[Finding] = field(default_factory=list)  # the record's
    unsupported: str = ""  # the model of a record on file no table reads (its unit is listed, not checked)

    @property
    def problems(self) -> list[Finding]:
        return [*self.unit.findings, *self.findings]

    @property
    def ok(self) -> bool:
        return not self.problems


def check_entry(entry: UnitEntry, *, source: ModelSource = ModelSource()) -> EntryCheck:
    out = EntryCheck(entry, check_unit(entry.folder, source=source))
    unit = out.unit.unit
    if entry.record is None or unit is None:
        return out
    try:
        out.record = read_record(entry.record, bus=unit.bus, machine_id=unit.machine_id, mva=unit.mva)
    except UnsupportedRecord as e:  # a governor of another family: listed, not a mistake in the unit
        out.unsupported = e.model
        return out
    except RapidCosimError as e:
        out.findings.append(finding(e))
        return out
    names = [s.name for s in out.unit.structures]
    if out.record.block not in names and len(out.unit.structures) == len(unit.structures):
        out.findings.append(Finding(str(unit.path), "structures.files",
                                    f"the record on file ({entry.record}, line {out.record.line}) is "
                                    f"{out.record.model}, and the unit's structures ({', '.join(names)}) have none: "
                                    f"add its structure file"))
    return out
