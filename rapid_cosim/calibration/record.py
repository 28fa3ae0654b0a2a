"""A calibration as the values of its standard governor's record (TGOV1, IEEEG1, GGOV1,
HYGOV), each value told where it came from: estimated, documented (fixed in the
experiments), the bench's default, or derived from the others (IEEEG1's K3 with
``K3_rest = 1``).

Here, below the API and the reports, so that ``rc.export`` (which writes the record) and
the validation report (which shows it) take the same values by the same rules.

Why every parameter: the record must be the model that was fitted. A value left out is
written at the table's default, whatever the fit ran with; IEEEG1's ``K3_rest`` was once
left out (it has no field), and every IEEEG1 record said K3 = 0.3 where the fit used
1 - K1. So the values are those of every parameter of the block but its operating point
(:attr:`~rapid_cosim.exchange.tables.Model.record_params`), and :mod:`.delivery` checks
the written file against the fit before it is handed over.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import ArchiveError, ConfigError
from ..exchange import MODELS
from ..exchange.tables import Model
from ..simulator import get_simulator
from .inputs import RunInputs

ESTIMATED, DOCUMENTED, DEFAULT, DERIVED = "estimated", "documented", "bench default", "derived"


@dataclass(frozen=True)
class RecordValues:
    """The standard model carried by a run's bench, its parameters' values (iGrGen names,
    without ``gov.``) as the record states them, and where each came from
    (:data:`ESTIMATED`, :data:`DOCUMENTED`, :data:`DEFAULT`, :data:`DERIVED`)."""

    model: Model
    values: dict[str, float]
    origin: dict[str, str]


def standard_model(inputs: RunInputs, *, source: str) -> tuple[Model, dict[str, float]]:
    """The standard model the run's one bench carries, and the bench's settable ``gov.*``
    start values (iGrGen names). Refused: experiments on several benches, a bench that
    carries none."""
    models = {e.model for e in inputs.experiments}
    if len(models) != 1:
        raise ConfigError(f"{source}: its experiments run {len(models)} models ({', '.join(sorted(models))}); "
                          "a record describes one")
    (bench,) = models
    starts = {n[4:]: p.start for n, p in get_simulator(inputs.fmus[bench]).parameters.items()
              if n.startswith("gov.") and p.settable}

    def carries(m: Model) -> bool:  # every parameter of the block, an operating point possibly bound (GGOV1's Pmwset)
        return set(m.required_params) <= set(starts) <= set(m.params)

    model = next((m for m in MODELS.values() if carries(m)), None)
    if model is None:
        raise ConfigError(f"{source}: its bench {bench} carries none of the standard governors "
                          f"({', '.join(MODELS)}); only their calibrations have a record")
    return model, starts


def standard_record(inputs: RunInputs, parameters: Mapping[str, float], x, *, source: str) -> RecordValues:
    """The record values of the run whose ``inputs`` and best ``parameters`` (by name; ``x``
    the same as an array, checked finite) are given; ``source`` names the run in errors.
    The values are the estimates over the experiments' fixed values over the bench's
    defaults, for every parameter of the block but its operating point, then resolved as
    the record states them (IEEEG1's K3 in use). Refused: a parameter fixed at different
    values or estimated per experiment."""
    model, starts = standard_model(inputs, source=source)
    wanted = set(model.record_params)
    values = {k: float(v) for k, v in starts.items() if k in wanted and v is not None}
    origin = {k: DEFAULT for k in values}
    fixed: dict[str, dict[str, float]] = {}
    for exp in inputs.experiments:
        for name, v in exp.fixed.items():
            if name.startswith("gov.") and name[4:] in wanted:
                fixed.setdefault(name[4:], {})[exp.name] = float(v)
    for key, by_experiment in fixed.items():
        if len(set(by_experiment.values())) > 1:
            raise ConfigError(f"{source}: gov.{key} is fixed at different values in its experiments "
                              f"({by_experiment}); a record holds one value")
        values[key], origin[key] = next(iter(by_experiment.values())), DOCUMENTED
    if not np.all(np.isfinite(np.asarray(x, dtype=float))):
        raise ArchiveError(f"{source}: no finite best point for a record")
    for name, v in parameters.items():
        if name.startswith("gov."):
            if "@" in name:
                raise ConfigError(f"{source}: {name.split('@')[0]} is estimated per experiment; a record holds "
                                  "one value")
            values[name[4:]], origin[name[4:]] = float(v), ESTIMATED
    missing = sorted(set(model.required_params) - set(values))
    if missing:
        raise ConfigError(f"{source}: no value for {', '.join(missing)} of {model.name} (the bench gives none)")
    resolved = model.resolve(dict(values)) if model.resolve else values
    origin.update({k: f"{DERIVED}: {model.derived}" for k, v in resolved.items() if v != values.get(k)})
    return RecordValues(model, resolved, origin)


def finished_run(path) -> tuple[RunInputs, dict[str, float], np.ndarray]:
    """A finished run's inputs, best parameters by name and best point, from its archive
    alone (a record is written from a finished run only)."""
    from ..archive import RunArchive
    from .inputs import inputs_from_archive

    with RunArchive(path) as view:
        inputs = inputs_from_archive(view)
        result = view.result()
        status = view.status
    if result is None:
        raise ArchiveError(f"{path}: the run has not finished ({status}); a record is written from a finished run "
                           "only")
    x = np.asarray(result.x, dtype=float)
    return inputs, dict(zip(result.names, x.tolist())), x


def archived_record(path) -> RecordValues:
    """The record values of a finished run's archive, as ``rapid-cosim export`` writes
    them (for studies below the API layer)."""
    inputs, parameters, x = finished_run(path)
    return standard_record(inputs, parameters, x, source=str(path))
