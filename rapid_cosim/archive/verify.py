"""Walk a whole archive and say, part by part, whether it is intact."""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass

from ..errors import ArchiveDamaged, ArchiveError
from . import format as fmt
from .reader import RunArchive


@dataclass(frozen=True)
class PartCheck:
    part: str
    intact: bool
    detail: str = ""


def verify(path: str | os.PathLike) -> list[PartCheck]:
    """Every part of the archive checked: header, counts, status, each config, the run
    options, each FMU, each experiment's data, every iteration and the result."""
    path = os.fspath(path)
    try:
        view = RunArchive(path)
    except ArchiveDamaged as e:
        return [PartCheck(e.part, False, e.reason)]
    with view:
        checks = [PartCheck("HDF5 structure", True, "sealed, intact" if view.checksums else "no seal (format 1)"),
                  PartCheck("header", True, f"format {view.format_version}" +
                            ("" if view.checksums else ", written before archives carried checksums"))]
        checks += [PartCheck(d.part, False, d.reason) for d in view.damaged]
        noted = {d.part for d in view.damaged}
        if "iteration count (/committed)" not in noted:
            checks.append(PartCheck("iteration count (/committed)", True,
                                    f"{view.n_iterations} iterations, {view.n_evaluations} evaluations"))
        if "status" not in noted:
            checks.append(PartCheck("status", True, view.status))
        checks += _inputs(view)
        its, damage = view.intact_iterations()
        if damage is not None and damage in view.damaged:
            pass  # already listed
        elif damage is None:
            checks.append(PartCheck("iterations", True, f"all {len(its)} intact"))
        else:
            checks.append(PartCheck(damage.part, False, f"{damage.reason}; iterations 0 to {len(its) - 1} intact"
                                    if its else damage.reason))
        if view.status is fmt.RunStatus.FINISHED and damage is None:
            try:
                view.result()
                checks.append(PartCheck("result", True))
            except ArchiveDamaged as e:
                checks.append(PartCheck(e.part, False, e.reason))
    return checks


def _inputs(view: RunArchive) -> list[PartCheck]:
    out = []
    for group, check in (("configs", _text), ("fmus", _sha), ("data", _data)):
        try:
            with view.guard(group):
                items = list(fmt.keyed(view._f[f"inputs/{group}"]).items())
        except ArchiveDamaged as e:
            out.append(PartCheck(e.part, False, e.reason))
            continue
        for key, obj in items:
            part = f"{group[:-1] if group != 'data' else 'data'} {key!r}"
            try:
                with view.guard(part):
                    check(view, obj)
                out.append(PartCheck(part, True))
            except ArchiveDamaged as e:
                out.append(PartCheck(e.part, False, e.reason))
    try:
        view.options
        out.append(PartCheck("run options", True))
    except ArchiveError as e:
        out.append(PartCheck("run options", False, getattr(e, "reason", str(e))))
    return out


def _text(view, ds) -> None:
    view._checked_text(ds)


def _sha(view, ds) -> None:
    if hashlib.sha256(ds[()].tobytes()).hexdigest() != ds.attrs["sha256"]:
        raise ValueError("does not match its stored sha256")


def _data(view, g) -> None:
    columns = {col: ds[()] for col, ds in fmt.keyed(g).items()}
    if fmt.data_sha256(columns) != g.attrs["sha256"]:
        raise ValueError("does not match its stored sha256")
