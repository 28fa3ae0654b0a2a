"""The record tables of the standard governors, one per layout a grid simulator reads:
TGOV1, IEEEG1, GGOV1, HYGOV and GAST as the PSS/E Model Library and PSLF give them, and the
deadband layouts TGOV1D, IEEEG1D and HYGOVD (PowerWorld's and ORNL GridKit's: the plain
model's fields, then ``dbH``, ``dbL`` in pu of speed and ``Trate``). What a table is and
every conversion: :mod:`.tables`.

Where each layout is read, and how it was checked (docs/identify.md has the table):

* TGOV1, IEEEG1, GAST: PSS/E ``.dyr``, read by ANDES 2.0's own parser in the tests and in
  ``make bench-replay`` (closed loop in its Kundur grid);
* TGOV1D: PowerWorld's layout; ANDES has the same block (TGOV1DB, the no-step deadband
  DeadBand1 on the speed deviation, dbL and dbU) but no ``.dyr`` entry for it, so the
  replay reads the record's numbers by PowerWorld's field list and builds ANDES's
  TGOV1DB from them (``experiments/electrical/andes_grid.py``);
* IEEEG1D, HYGOVD: PowerWorld's and GridKit's layouts, checked against their own block
  diagrams only (no simulator here has them; ANDES's HYGOV lacks PSS/E's 1/(r Tr) gain);
* GGOV1 (its own ``db``), HYGOV: PSS/E and PSLF, checked against their block diagrams.

PSLF has no deadband layout written here: its ieeeg1 and hygov deadbands ``db1`` (Hz),
``eps`` (a hysteresis, Hz) and ``db2`` (MW) are of another form and base, so a record with
a deadband is written as a ``.dyr`` only, and a ``.dyd`` says why not (:mod:`.pslf_dyd`).
"""

from __future__ import annotations

import math

from ..errors import ParameterError
from .tables import Dropped, Field, Model, layout_for

_OPERATING = "operating point: the grid simulator initialises it from its power flow"
_SHARP = "sharpness of iGrGen's smooth limits: the grid simulators' limits are exact"


_DEADBAND = "the deadband on the speed deviation: the plain layout has no field for it"


def _common(*extra: Dropped) -> tuple[Dropped, ...]:
    return (Dropped("p_ref", None, _OPERATING, operating=True), Dropped("eps_v", 1e-4, _SHARP), Dropped("K_lim", 100.0, _SHARP),
            *extra)


def _plain(layout: str) -> tuple[Dropped, ...]:
    """What a block with a speed deadband drops in its plain layout: the deadband (carried
    by ``layout``) and its corners' sharpness."""
    return (Dropped("db", 0.0, _DEADBAND, layout=layout, newer=True), Dropped("eps_db", 1e-6, _SHARP, newer=True))


def _with_deadband(plain: Model, name: str) -> Model:
    """``plain``'s layout with a deadband: its fields, then dbH = db, dbL = -db (pu of
    speed) and Trate (0: the machine base), as PowerWorld and ORNL GridKit give TGOV1D,
    IEEEG1D and HYGOVD. No PSLF layout."""
    fields = (*plain.fields, Field("dbH", None, "db", 0.0, 0, 0.01), Field("dbL", None, "db", 0.0, 0, 0.01, scale=-1.0),
              Field("Trate", None, None, 0.0, 0.0, math.inf, keep=True))
    dropped = tuple(d for d in plain.dropped if d.param != "db")  # eps_db stays: newer, sharpness
    return Model(name, fields, (), dropped, plain.resolve, plain.derived, family=plain.name, pslf=False)


def _f(psse: str, param: str | None, default: float, lo: float = -math.inf, hi: float = math.inf, **kw) -> Field:
    return Field(psse, kw.pop("pslf", psse.lower()), param, default, lo, hi, **kw)


def _none(psse: str, default: float, pslf: str | None = None) -> Field:
    """A field without a counterpart that must hold ``default`` for the iGrGen model."""
    return Field(psse, pslf, None, default)


TGOV1 = Model("TGOV1", (
    _f("R", "R", 0.05, 0.001, 1), _f("T1", "T1", 0.5, 0.001, 100), _f("VMAX", "VMAX", 1.0, 0, 2),
    _f("VMIN", "VMIN", 0.0, 0, 2), _f("T2", "T2", 2.5, 0, 100), _f("T3", "T3", 7.5, 0.001, 100),
    _f("Dt", "Dt", 0.0, 0, 10),
), ("r", "t1", "vmax", "vmin", "t2", "t3", "dt"), _common(*_plain("TGOV1D")))
TGOV1D = _with_deadband(TGOV1, "TGOV1D")


def _ieeeg1_stages(values: dict) -> dict:
    """With K3_rest = 1 the record carries the K3 in use, 1 - K1 - K5 - K7 (as the model's
    ``K3s``): the stages sum to one in the .dyr as in the model. A missing K1, K5 or K7 is
    the model's default, as in the model."""
    if values.get("K3_rest", 0.0) <= 0.5:
        return values
    rest = 1.0 - values.get("K1", 0.2) - values.get("K5", 0.5) - values.get("K7", 0.0)
    return {**values, "K3": rest}


IEEEG1 = Model("IEEEG1", (
    Field("JBUS", None, None, 0.0, integer=True), Field("M", None, None, 0.0, integer=True),
    _f("K", "K", 20.0, 1, 100), _f("T1", "T1", 0.001, 0.001, 100, zero_as=0.001), _f("T2", "T2", 0.0, 0, 100),
    _f("T3", "T3", 0.1, 0.001, 10), _f("Uo", "Uo", 1.0, 1e-4, 10), _f("Uc", "Uc", -1.0, -10, -1e-4),
    _f("PMAX", "PMAX", 1.0, 0, 2), _f("PMIN", "PMIN", 0.0, 0, 2), _f("T4", "T4", 0.3, 0.001, 100),
    _f("K1", "K1", 0.2, 0, 1), _none("K2", 0.0, "k2"), _f("T5", "T5", 7.0, 0.001, 100), _f("K3", "K3", 0.3, 0, 1),
    _none("K4", 0.0, "k4"), _f("T6", "T6", 0.6, 0.001, 100), _f("K5", "K5", 0.5, 0, 1), _none("K6", 0.0, "k6"),
    _f("T7", "T7", 0.05, 0.001, 100), _f("K7", "K7", 0.0, 0, 1), _none("K8", 0.0, "k8"),
), ("k", "t1", "t2", "t3", "uo", "uc", "pmax", "pmin", "t4", "k1", "k2", "t5", "k3", "k4", "t6", "k5", "k6", "t7",
    "k7", "k8"), _common(Dropped("K3_rest", None, "with 1, written into K3 as 1 - K1 - K5 - K7; a record read states "
                                 "its K3 (0)", read_as=0.0), *_plain("IEEEG1D")), _ieeeg1_stages,
    "K3 = 1 - K1 - K5 - K7, the rest of the shaft (K3_rest = 1)")
IEEEG1D = _with_deadband(IEEEG1, "IEEEG1D")

GGOV1 = Model("GGOV1", (
    _f("Rselect", "Rselect", 1.0, -1, 1, integer=True, choices=(-1.0, 0.0, 1.0)),
    _f("Flag", "Flag", 1.0, 0, 1, integer=True, choices=(0.0, 1.0)),
    _f("R", "R", 0.04, 0, 1), _f("Tpelec", "Tpelec", 1.0, 0.001, 10), _f("maxerr", "maxerr", 0.05, 0, 1),
    _f("minerr", "minerr", -0.05, -1, 0), _f("Kpgov", "Kpgov", 10.0, 0, 100), _f("Kigov", "Kigov", 2.0, 0, 100),
    _f("Kdgov", "Kdgov", 0.0, 0, 100), _f("Tdgov", "Tdgov", 1.0, 0.001, 10), _f("Vmax", "Vmax", 1.0, 0, 2),
    _f("Vmin", "Vmin", 0.15, 0, 1), _f("Tact", "Tact", 0.5, 0.001, 10), _f("Kturb", "Kturb", 1.5, 0.1, 5),
    _f("Wfnl", "Wfnl", 0.2, 0, 1), _f("Tb", "Tb", 0.5, 0.001, 100), _f("Tc", "Tc", 0.0, 0, 100),
    _none("Teng", 0.0, "teng"), _f("Tfload", "Tfload", 3.0, 0.001, 100), _f("Kpload", "Kpload", 2.0, 0, 100),
    _f("Kiload", "Kiload", 0.67, 0, 100), _f("Ldref", "Ldref", 1.0, 0, 2), _f("Dm", "Dm", 0.0, 0, 1),
    _f("Ropen", "Ropen", 0.1, 1e-4, 100), _f("Rclose", "Rclose", -0.1, -100, -1e-4), _f("Kimw", "Kimw", 0.0, 0, 1),
    _f("Aset", "aset", 0.1, -1, 10), _f("Ka", "Ka", 10.0, 0, 100), _f("Ta", "Ta", 0.1, 0.001, 10),
    Field("Trate", None, None, 0.0, 0.0, math.inf, keep=True), _f("db", "db", 0.0, 0, 0.1),
    _f("Tsa", "Tsa", 4.0, 0, 100), _f("Tsb", "Tsb", 5.0, 0.001, 100),
    Field("Rup", "rup", None, 99.0, keep=True), Field("Rdown", "rdown", None, -99.0, keep=True),
    Field(None, "pmwset", None, 0.0, keep=True),
), ("r", "rselect", "tpelec", "maxerr", "minerr", "kpgov", "kigov", "kdgov", "tdgov", "vmax", "vmin", "tact",
    "kturb", "wfnl", "tb", "tc", "flag", "teng", "tfload", "kpload", "kiload", "ldref", "dm", "ropen", "rclose",
    "kimw", "pmwset", "aset", "ka", "ta", "db", "tsa", "tsb", "rup", "rdown"),
    _common(Dropped("Pmwset", None, _OPERATING + " (PSS/E sets it to the initial power)", operating=True),
            Dropped("eps_db", 1e-6, _SHARP, newer=True),
            Dropped("K_track", 10.0, "tracking gain of iGrGen's smooth anti-windup; PSS/E's gate is exact"),
            Dropped("DELT", 0.005, "PSS/E's own time step, which iGrGen's acceleration limiter stands in for")))

HYGOV = Model("HYGOV", (
    _f("R", "R", 0.05, 0.001, 1, pslf="rperm"), _f("r", "r", 0.3, 0.001, 5, pslf="rtemp"),
    _f("Tr", "Tr", 5.0, 0.001, 100),
    _f("Tf", "Tf", 0.05, 0.001, 10), _f("Tg", "Tg", 0.5, 0.001, 10), _f("VELM", "VELM", 0.2, 1e-4, 10),
    _f("GMAX", "GMAX", 1.0, 0, 2), _f("GMIN", "GMIN", 0.0, 0, 2), _f("TW", "TW", 1.0, 0.01, 10),
    _f("At", "At", 1.2, 0.5, 2), _f("Dturb", "Dturb", 0.5, 0, 5), _f("qNL", "qNL", 0.08, 0, 0.5),
), ("rperm", "rtemp", "tr", "tf", "tg", "velm", "gmax", "gmin", "tw", "at", "dturb", "qnl"), _common(*_plain("HYGOVD")))
HYGOVD = _with_deadband(HYGOV, "HYGOVD")

GAST = Model("GAST", (
    _f("R", "R", 0.05, 0.001, 1), _f("T1", "T1", 0.4, 0.001, 100), _f("T2", "T2", 0.1, 0.001, 100),
    _f("T3", "T3", 3.0, 0.001, 100), _f("AT", "AT", 1.0, 0, 2), _f("KT", "KT", 2.0, 0, 10),
    _f("VMAX", "VMAX", 1.0, 0, 2), _f("VMIN", "VMIN", 0.0, -1, 2), _f("Dt", "Dt", 0.0, 0, 10, pslf="dturb"),
), ("r", "t1", "t2", "t3", "at", "kt", "vmax", "vmin", "dturb"), _common())

# The iGrGen blocks a structure and a fit name (one table each, the plain layout), and
# every layout a file may hold.
MODELS: dict[str, Model] = {m.name: m for m in (TGOV1, IEEEG1, GGOV1, HYGOV, GAST)}
LAYOUTS: dict[str, Model] = {m.name: m for m in (TGOV1, TGOV1D, IEEEG1, IEEEG1D, GGOV1, HYGOV, HYGOVD, GAST)}
SUPPORTED = ", ".join(LAYOUTS)


def model_named(name: str) -> Model:
    """The table of a layout, by PSS/E or PSLF name (any case)."""
    model = LAYOUTS.get(name.upper())
    if model is None:
        raise ParameterError(f"no record table for model {name!r}; the layouts read and written: {SUPPORTED}")
    return model


def layout(model: str, values) -> Model:
    """The layout a record of block ``model`` with ``values`` is written in (TGOV1 with a
    deadband: TGOV1D)."""
    return layout_for(model_named(model), values, LAYOUTS)


