"""A calibration as the values of its standard governor's record (TGOV1, IEEEG1, GGOV1,
HYGOV), each value told where it came from: estimated, documented (fixed in the
experiments) or the bench's default.

Here, below the API and the reports, so that ``rc.export`` (which writes the record) and
the validation report (which shows it) take the same values by the same rules.
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

ESTIMATED, DOCUMENTED, DEFAULT = "estimated", "documented", "bench default"


@dataclass(frozen=True)
class RecordValues:
    """The standard model carried by a run's bench, its parameters' values (iGrGen names,
    without ``gov.``) and where each came from (:data:`ESTIMATED`, :data:`DOCUMENTED`,
    :data:`DEFAULT`)."""

    model: Model
    values: dict[str, float]
    origin: dict[str, str]


def standard_record(inputs: RunInputs, parameters: Mapping[str, float], x, *, source: str) -> RecordValues:
    """The record values of the run whose ``inputs`` and best ``parameters`` (by name; ``x``
    the same as an array, checked finite) are given; ``source`` names the run in errors.
    The values are the estimates over the experiments' fixed values over the bench's
    defaults. Refused: experiments on several benches, a bench that carries no standard
    governor, a parameter fixed at different values or estimated per experiment."""
    experiments = inputs.experiments
    models = {e.model for e in experiments}
    if len(models) != 1:
        raise ConfigError(f"{source}: its experiments run {len(models)} models ({', '.join(sorted(models))}); "
                          "a record describes one")
    (bench,) = models
    starts = {n[4:]: p.start for n, p in get_simulator(inputs.fmus[bench]).parameters.items()
              if n.startswith("gov.") and p.settable}

    def carries(m) -> bool:  # every parameter of the block, an operating point possibly bound (GGOV1's Pmwset)
        return set(m.params) - {d.param for d in m.dropped if d.default is None} <= set(starts) <= set(m.params)

    model = next((m for m in MODELS.values() if carries(m)), None)
    if model is None:
        raise ConfigError(f"{source}: its bench {bench} carries none of the standard governors "
                          f"({', '.join(MODELS)}); only their calibrations have a record")
    carried = {f.param for f in model.fields if f.param} | {d.param for d in model.dropped if d.default is not None}
    values = {k: float(v) for k, v in starts.items() if k in carried and v is not None}
    origin = {k: DEFAULT for k in values}
    fixed: dict[str, dict[str, float]] = {}
    for exp in experiments:
        for name, v in exp.fixed.items():
            if name.startswith("gov.") and name[4:] in carried:
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
    return RecordValues(model, values, origin)


def archived_record(path) -> RecordValues:
    """The record values of a finished run's archive, as ``rapid-cosim export`` writes
    them (for studies below the API layer)."""
    from ..archive import RunArchive
    from .inputs import inputs_from_archive

    with RunArchive(path) as view:
        inputs = inputs_from_archive(view)
        result = view.result()
    if result is None:
        raise ArchiveError(f"{path}: the run has not finished; a record is written from a finished run only")
    x = np.asarray(result.x, dtype=float)
    return standard_record(inputs, dict(zip(result.names, x.tolist())), x, source=str(path))
