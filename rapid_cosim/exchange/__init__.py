"""Records in the grid simulators' formats: PSS/E ``.dyr`` (:mod:`.psse_dyr`) and PSLF
``.dyd`` (:mod:`.pslf_dyd`) of the standard governors TGOV1, IEEEG1, GGOV1 and HYGOV, both
mapped to iGrGen parameters by one table per model (:mod:`.tables`, where every
conversion is documented). Plain functions over dicts of parameter values: nothing here
knows of experiments, estimators or archives (as andes' ``io`` package)."""

from __future__ import annotations

from pathlib import Path

from ..errors import ParameterError
from . import pslf_dyd, psse_dyr
from .tables import MODELS, ExchangeWarning, Record, Written, model_named

FORMATS = {"dyr": psse_dyr, "dyd": pslf_dyd}


def format_of(path: str | Path) -> str:
    """``dyr`` or ``dyd``, from a file's suffix."""
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in FORMATS:
        raise ParameterError(f"{path}: a record file ends in .dyr (PSS/E) or .dyd (PSLF)")
    return suffix


def read_record(path: str | Path, *, bus: int | None = None, machine_id: str | None = None,
                mva: float | None = None) -> Record:
    """The one governor record of a ``.dyr`` or ``.dyd`` file (by its suffix). ``mva``, the
    machine base, lets a ``.dyr`` GGOV1 record on ``Trate`` = MBASE be read (a ``.dyd``
    record states its base)."""
    kind = format_of(path)
    options = {"mva": mva} if kind == "dyr" else {}
    return FORMATS[kind].read_record(path, bus=bus, machine_id=machine_id, **options)


__all__ = ["FORMATS", "MODELS", "ExchangeWarning", "Record", "Written", "format_of", "model_named", "pslf_dyd",
           "psse_dyr", "read_record"]
