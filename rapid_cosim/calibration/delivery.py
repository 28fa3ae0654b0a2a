"""A record is handed over only when it is the model that was fitted.

The record is written next to its destination, read back by the format's reader, and
played as a grid simulator plays it (:meth:`~rapid_cosim.exchange.tables.Model.played`:
the record's fields win; each test's operating point and other blocks are the test's;
what the record has no field for is the bench's default). Every test of the fit is then
simulated with it and with the fitted values; where the two differ by more than
:data:`REPRODUCE_PU` anywhere, the file is removed and :class:`DeliveryError` says by how
much, where, and which values the record could not carry. Only then is it moved into
place, so a wrong record never lands on file.

Why here and not in the writer: the writer knows tables of numbers; only a simulation
shows that the numbers mean the model. A wrong K3 read the same way twice (written at a
default, played back with the structure's ``K3_rest``) passed every round trip through
the project's own reader, and missed in ANDES by 20 % at the peak.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import DeliveryError, RapidCosimError
from ..exchange import FORMATS, Record, Written
from ..exchange.tables import Model
from ..fitting.objective import simulate_experiment
from .inputs import RunInputs
from .record import RecordValues, finished_run, standard_model, standard_record

REPRODUCE_PU = 1e-9  # a record read back simulates its fit to this (pu), everywhere the fit scores
DISPATCH = "p_ref"  # the one parameter of a block a grid simulator takes from the event (its power flow)


@dataclass(frozen=True)
class Reproduction:
    """A record read back against its fit: per test, the largest difference of any output
    at any sample the fit scores (pu)."""

    record: Record
    errors: dict[str, float]

    @property
    def worst(self) -> float:
        return max(self.errors.values(), default=0.0)

    @property
    def reproduces(self) -> bool:
        return all(math.isfinite(e) and e <= REPRODUCE_PU for e in self.errors.values())


@dataclass(frozen=True)
class Delivered:
    """A record written and checked: the file, and how closely it reproduces its fit."""

    written: Written
    reproduction: Reproduction

    @property
    def model(self) -> str:
        return self.written.model

    @property
    def path(self) -> str | None:
        return self.written.path

    @property
    def text(self) -> str:
        return self.written.text

    @property
    def dropped(self) -> dict[str, float]:
        return self.written.dropped


def played_parameters(model: Model, record: Mapping[str, float], fitted: Mapping[str, float]) -> dict[str, float]:
    """One test's parameters with ``record`` (iGrGen names) in place of the fitted model's
    block: the test's own values except the block's (its dispatch ``p_ref`` kept, as a
    grid simulator's power flow sets it), the record's over them, the bench's defaults
    for the rest (GGOV1's Pmwset is then the dispatch, as PSS/E sets it)."""
    block = set(model.params) - {DISPATCH}
    context = {k: v for k, v in fitted.items() if not (k.startswith("gov.") and k[4:] in block)}
    return model.played(record, context)


def reproduction(inputs: RunInputs, x, model: Model, record: Record) -> Reproduction:
    """``record`` against the fit at ``x`` on every test of ``inputs``."""
    errors = {}
    for i, exp in enumerate(inputs.experiments):
        fitted = inputs.problem.parameters_for(x, i)
        fmu = inputs.fmus[exp.model]
        try:
            a = simulate_experiment(exp, fmu, fitted)
            b = simulate_experiment(exp, fmu, played_parameters(model, record.values, fitted))
        except RapidCosimError as e:
            raise DeliveryError(f"{record.file}: the record read back could not be simulated on {exp.name}: {e}") \
                from None
        errors[exp.name] = max(float(np.max(np.abs(a[n] - b[n]), initial=0.0)) for n in exp.outputs)
    return Reproduction(record, errors)


def plain_departure(path, record: Record) -> dict[str, tuple[float, float]]:
    """What a simulator that reads only the plain layout loses of ``record`` (a TGOV1D read
    as a TGOV1: no deadband), on every test of the finished run in ``path``: per test, the
    largest difference from the fit (pu) and the fit's own excursion (pu), to say it as a
    share."""
    inputs, _, x = finished_run(path)
    model, _ = standard_model(inputs, source=str(path))
    plain = {**record.values, **{d.param: d.default for d in model.dropped if d.layout is not None}}
    out = {}
    for i, exp in enumerate(inputs.experiments):
        fitted = inputs.problem.parameters_for(x, i)
        fmu = inputs.fmus[exp.model]
        a = simulate_experiment(exp, fmu, fitted)
        b = simulate_experiment(exp, fmu, played_parameters(model, plain, fitted))
        out[exp.name] = (max(float(np.max(np.abs(a[n] - b[n]), initial=0.0)) for n in exp.outputs),
                         max(float(np.ptp(a[n])) for n in exp.outputs))
    return out


def deliver_record(inputs: RunInputs, parameters: Mapping[str, float], x, out: str | Path, *, kind: str,
                   bus: int = 1, machine_id: str = "1", mva: float | None = None, bus_name: str = "",
                   kv: float = 0.0, source: str) -> Delivered:
    """Write the run's standard record (``kind`` ``dyr`` or ``dyd``) to ``out`` only if it
    reproduces the fit (module docstring); ``source`` names the run in errors."""
    record = standard_record(inputs, parameters, x, source=source)
    out = Path(out)
    trial = out.with_name(f".{out.name}.checking")
    fmt = FORMATS[kind]
    options = {"mva": mva, "bus_name": bus_name, "kv": kv} if kind == "dyd" else {}
    try:
        written = fmt.write_record(trial, record.model.name, record.values, bus=bus, machine_id=machine_id,
                                   **options)
        read = fmt.read_record(trial, bus=bus, machine_id=machine_id, **({"mva": mva} if kind == "dyr" else {}))
        read = replace(read, file=str(out))  # errors name the file the user asked for, not the trial copy
        check = reproduction(inputs, x, record.model, read)
        if not check.reproduces:
            raise DeliveryError(_refusal(out, record, check, inputs, x))
        os.replace(trial, out)
    finally:
        trial.unlink(missing_ok=True)
    return Delivered(Written(written.model, written.text, str(out), written.dropped), check)


def deliver_archived(path, out: str | Path, *, kind: str, **where) -> Delivered:
    """:func:`deliver_record` of a finished run's archive (``where``: bus, machine_id, mva,
    bus_name, kv)."""
    inputs, parameters, x = finished_run(path)
    return deliver_record(inputs, parameters, x, out, kind=kind, source=str(path), **where)


def archived_reproduction(path, record: Record) -> Reproduction:
    """A record read from a file against the finished run in ``path`` it was written
    from: what a caller that did not write it checks (the fleet, of identify's files)."""
    inputs, _, x = finished_run(path)
    model, _ = standard_model(inputs, source=str(path))
    if record.block != model.name:
        raise DeliveryError(f"{record.file}: a {record.model} record, where the run {path} fitted {model.name}")
    return reproduction(inputs, x, model, record)


def _refusal(out: Path, record: RecordValues, check: Reproduction, inputs: RunInputs, x) -> str:
    """Why a record is not handed over: where it misses its fit, by how much, and the
    fitted values it cannot carry."""
    where = max(check.errors, key=lambda k: check.errors[k] if math.isfinite(check.errors[k]) else math.inf)
    fitted = inputs.problem.parameters_for(x, 0)
    model = record.model
    lost = []
    for d in model.dropped:
        if d.operating or d.read_as is not None:
            continue
        name = f"gov.{d.param}"
        if name in fitted and d.default is not None and not math.isclose(fitted[name], d.default, rel_tol=1e-12):
            lost.append(f"{name} = {fitted[name]:g} (no field: the record means {d.default:g})")
    cause = f"; the record cannot carry {', '.join(lost)}" if lost else ""
    return (f"{out}: not written: the {model.name} record, read back, does not reproduce the fit it was written from "
            f"(largest difference {check.errors[where]:.3g} pu on {where}, allowed {REPRODUCE_PU:g}){cause}")
