"""Records in the grid simulators' formats: PSS/E ``.dyr`` (:mod:`.psse_dyr`) and PSLF
``.dyd`` (:mod:`.pslf_dyd`) of the standard governors TGOV1, IEEEG1, GGOV1, HYGOV and GAST
and the deadband layouts TGOV1D, IEEEG1D, HYGOVD, both mapped to iGrGen parameters by one
table per layout (:mod:`.layouts`; what a table is and every conversion: :mod:`.tables`). Plain functions over dicts of parameter values: nothing here
knows of experiments, estimators or archives (as andes' ``io`` package).

The inertia constant H and damping D that an electrical-power event estimates (the
benches' ``mach.H``, ``mach.D``) are the machine's, not the governor's: no governor record
has a field for them. They belong in the unit's generator record, GENROU for a round-rotor
unit (GENSAL salient-pole, GENCLS classical: the same two fields): in a PSS/E ``.dyr``
record ``IBUS 'GENROU' ID T'do T''do T'qo T''qo H D Xd Xq ...`` H is CON(J+4), the fifth
value after the machine's ID, and D CON(J+5), the sixth; in a PSLF ``.dyd`` ``genrou``
record they are ``h`` and ``d``. Both are on the machine's MVA base, as here. A machine
record also needs the reactances and time constants no test here estimates, so none is
written: :func:`machine_note` says what to change in the unit's own record."""

from __future__ import annotations

from pathlib import Path

from ..errors import ParameterError
from . import pslf_dyd, psse_dyr
from .layouts import LAYOUTS, MODELS, SUPPORTED, layout, model_named
from .tables import ExchangeWarning, NoLayout, Other, Record, UnsupportedRecord, Written

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


MACHINE_FIELDS = {  # parameter -> (PSS/E .dyr GENROU position, PSLF .dyd genrou keyword, unit)
    "mach.H": ("CON(J+4), the 5th value after the ID", "h", "s"),
    "mach.D": ("CON(J+5), the 6th value after the ID", "d", "pu"),
}


def machine_note(values: dict[str, float], kind: str) -> str | None:
    """What a governor record cannot carry of ``values`` (``mach.H``, ``mach.D``), and
    where in the unit's generator record it goes; None when there is nothing."""
    fields = [(n, v, *MACHINE_FIELDS[n]) for n, v in values.items() if n in MACHINE_FIELDS]
    if not fields:
        return None
    where = "; ".join(f"{n[5:]} = {v:.4g} {unit} as {dyr if kind == 'dyr' else repr(dyd)}"
                      for n, v, dyr, dyd, unit in fields)
    record = "PSS/E .dyr 'GENROU' (or GENSAL, GENCLS)" if kind == "dyr" else "PSLF .dyd genrou (or gensal, gencls)"
    return (f"the machine's constants are not in the governor's record: write {where} in the unit's {record} "
            "record, on the machine's MVA base")


__all__ = ["MACHINE_FIELDS", "machine_note", "FORMATS", "LAYOUTS", "MODELS", "SUPPORTED", "ExchangeWarning", "NoLayout", "Other",
           "Record", "UnsupportedRecord", "Written", "format_of", "layout", "model_named", "pslf_dyd", "psse_dyr",
           "read_record"]
