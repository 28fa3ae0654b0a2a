"""One table per standard model: the fields of its PSS/E and PSLF records and the iGrGen
parameter each one carries, shared by :mod:`.psse_dyr` and :mod:`.pslf_dyd`.

Why a table: both formats are positional lists of numbers whose meaning is fixed by the
simulator's model library, and a wrong position is a silent error. Keeping the mapping in
one place, with the iGrGen default and range of every parameter (checked against
``modelica/iGrGen/Governors/*.mo`` by ``tests/test_exchange.py``), makes both formats agree
by construction.

Conversions (the same for both formats)
---------------------------------------
* **Bases.** All four iGrGen governors are in pu on the machine's MVA base, as the PSS/E
  Model Library and PSLF give them: values are written and read **unchanged**. A ``.dyr``
  record carries no base (PSS/E takes the machine's MBASE from the ``.raw`` generator
  record); a ``.dyd`` record states it as ``mva=``. GGOV1's ``Trate`` (PSS/E's turbine rating,
  MW) is written 0, which PSS/E reads as "the machine base"; a record with another ``Trate``
  is read only when it equals the machine base given by the caller (the iGrGen model has
  no turbine base to convert to).
* **Signs.** PSS/E's speed input is ``SPEED = w - 1``; the iGrGen blocks take
  ``dw = w_ref - w``, and their equations carry the sign (``u = p_ref + dw / R`` is PSS/E's
  ``P_ref - SPEED / R``). So every gain and damping (``R``, ``K``, ``Dt``, ``Dm``, ``Dturb``)
  keeps its value and its sign. Closing rates are negative in both (``Uc``, ``Rclose``).
* **Zero time constants.** PSS/E allows IEEEG1's ``T1 = 0`` (no lag); the iGrGen block needs
  ``T1 >= 0.001`` s and treats 0.001 as "no lag". So a record's 0 is read as 0.001 and
  0.001 is written 0 (``Field.zero_as``).
* **Fields without a counterpart** are written at the neutral value that makes the record
  mean the iGrGen model (IEEEG1's second-machine ``JBUS``/``M`` and low-pressure fractions
  ``K2``, ``K4``, ``K6``, ``K8`` as 0, for a single shaft; GGOV1's ``Teng`` 0, ``Trate`` 0, ``Rup``
  99 and ``Rdown`` -99, PSS/E's "no ramp limit" of a load reference a test holds constant).
  PSLF's ggov1 also has ``pmwset``, the power controller's set-point in MW (PSS/E computes
  it from the initial power; iGrGen's ``Pmwset`` follows the dispatch, in pu): written 0,
  and a ggov1 record with ``kimw`` > 0 is neither written nor read (:mod:`.pslf_dyd`);
  the standard structures hold ``Kimw`` at 0.
  On reading, a value the iGrGen model cannot represent is an error naming the allowed
  value; ``Rup``/``Rdown`` (no effect while the load limit reference is constant),
  ``Trate`` and ``pmwset`` are kept in :attr:`Record.extra`, so a record read and written
  again is the same.
* **Parameters without a field** (:class:`Dropped`) are not written: the operating point
  (``p_ref``, GGOV1's ``Pmwset``), which the grid simulator takes from its power flow; the
  smooth limits' sharpness (``eps_v``, ``K_lim``, GGOV1's ``K_track``), which the grid
  simulators do not need (their limits are exact); GGOV1's ``DELT``, PSS/E's own time step.
  Writing one of the sharpness or ``DELT`` parameters away from its default warns
  (:class:`ExchangeWarning`): the record then means a slightly different model than the
  one calibrated. Reading a record gives them no value (the iGrGen defaults apply).
* **IEEEG1's stages.** ``K3_rest`` is how a structure *estimates* the stages (K3 the rest
  of the shaft, 1 - K1 - K5 - K7, so that they sum to one), not a field: the record
  carries the K3 in use, computed from the fitted K1, K5, K7 (``Model.resolve``). A record
  read back states its K3, so it reads with ``K3_rest = 0`` (``Dropped.read_as``), and a
  record is played with its own fields over any structure's values (``Model.played``):
  a record on file whose stages do not sum to one is played as it is written.
* **Ranges on writing.** A value the reader would refuse (outside the field's range, a
  resolved K3 below 0) is refused on writing too, so no file is written that its own
  reader cannot read.
* **Flags.** GGOV1's ``Rselect`` and ``Flag`` (PSS/E ICONs) are Integer parameters in
  iGrGen; they are written as integers. ``Rselect = -2`` has no iGrGen counterpart.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Callable, Mapping

from ..errors import ParameterError, RecordError


class ExchangeWarning(UserWarning):
    """A value that a record cannot carry was dropped while it differs from its default."""


@dataclass(frozen=True)
class Field:
    """One number of a record. ``param`` is the iGrGen parameter it carries (None: no
    counterpart, then ``default`` is written and ``allowed`` is what the iGrGen model can
    represent when read). ``lo``/``hi`` are the iGrGen parameter's declared range."""

    psse: str | None  # None: a PSLF-only field
    pslf: str | None  # None: a PSS/E-only field
    param: str | None
    default: float
    lo: float = -math.inf
    hi: float = math.inf
    integer: bool = False
    zero_as: float | None = None  # a record's 0 is this iGrGen value (and is written back as 0)
    keep: bool = False  # no counterpart, any value accepted and kept in Record.extra
    choices: tuple[float, ...] | None = None  # the only values allowed (flags)

    @property
    def key(self) -> str:
        """The field's name in both formats' dicts: PSS/E's, else PSLF's."""
        return self.psse or self.pslf

    def allowed(self) -> str:
        if self.choices is not None:
            return " or ".join(f"{c:g}" for c in self.choices)
        if self.param is None and not self.keep:
            return f"{self.default:g} (no iGrGen counterpart)"
        text = f"{self.lo:g} to {self.hi:g}"
        return f"0 or {text}" if self.zero_as is not None else text


@dataclass(frozen=True)
class Dropped:
    """An iGrGen parameter no record field carries, and why.

    ``operating``: an operating point, which the grid simulator sets from its power flow
    for each event; it is no part of a record, so a fit may hold it at another value per
    test. ``read_as``: the value a record read back means, where the parameter chooses
    how other fields are used (IEEEG1's ``K3_rest`` 0: K3 as the record states it)."""

    param: str
    default: float | None  # None: nothing to warn against when it is not written
    why: str
    operating: bool = False
    read_as: float | None = None


@dataclass(frozen=True)
class Model:
    """A standard model: its record fields in the PSS/E Model Library's order (ICONs
    first, as a ``.dyr`` record lists them), PSLF's keyword order, and the iGrGen
    parameters no field carries."""

    name: str
    fields: tuple[Field, ...]
    pslf_order: tuple[str, ...]
    dropped: tuple[Dropped, ...]
    resolve: Callable[[dict], dict] | None = None  # iGrGen values -> those the fields carry (K3 in use)
    derived: str = ""  # what resolve derives, in words

    @property
    def pslf_name(self) -> str:
        return self.name.lower()

    @property
    def params(self) -> tuple[str, ...]:
        """Every iGrGen parameter of the block (carried or dropped)."""
        return tuple(f.param for f in self.fields if f.param) + tuple(d.param for d in self.dropped)

    @property
    def record_params(self) -> tuple[str, ...]:
        """The parameters that make the record's model: all but the operating points. An
        export must know each one's value in the fit (a dropped one's decides what the
        fields say: IEEEG1's ``K3_rest``)."""
        operating = {d.param for d in self.dropped if d.operating}
        return tuple(p for p in self.params if p not in operating)

    def read_values(self, values: Mapping[str, float]) -> dict[str, float]:
        """``values`` as a record states them: with the values its reading implies
        (:attr:`Dropped.read_as`)."""
        return {**values, **{d.param: d.read_as for d in self.dropped if d.read_as is not None}}

    def played(self, values: Mapping[str, float], context: Mapping[str, float], prefix: str = "gov.") -> dict[str, float]:
        """A record's ``values`` (iGrGen names) as a grid simulator plays them, in a bench's
        names (``prefix``): the record's fields win; ``context`` (a structure's or a test's
        values, bench names) fills only what the record has no field for (the operating
        point, the smooth limits' sharpness, the bench's other blocks). A structure's
        ``K3_rest = 1`` is a way to estimate, never a reason to ignore the K3 a file
        states."""
        stated = {prefix + k: float(v) for k, v in self.read_values(values).items()}
        covered = {prefix + f.param for f in self.fields if f.param} | set(stated)
        return {**{k: v for k, v in context.items() if k not in covered}, **stated}

    @property
    def psse_fields(self) -> tuple[Field, ...]:
        return tuple(f for f in self.fields if f.psse is not None)

    def by_pslf(self) -> dict[str, Field]:
        return {f.pslf: f for f in self.fields if f.pslf is not None}


_OPERATING = "operating point: the grid simulator initialises it from its power flow"
_SHARP = "sharpness of iGrGen's smooth limits: the grid simulators' limits are exact"


def _common(*extra: Dropped) -> tuple[Dropped, ...]:
    return (Dropped("p_ref", None, _OPERATING, operating=True), Dropped("eps_v", 1e-4, _SHARP), Dropped("K_lim", 100.0, _SHARP),
            *extra)


def _f(psse: str, param: str | None, default: float, lo: float = -math.inf, hi: float = math.inf, **kw) -> Field:
    return Field(psse, kw.pop("pslf", psse.lower()), param, default, lo, hi, **kw)


def _none(psse: str, default: float, pslf: str | None = None) -> Field:
    """A field without a counterpart that must hold ``default`` for the iGrGen model."""
    return Field(psse, pslf, None, default)


TGOV1 = Model("TGOV1", (
    _f("R", "R", 0.05, 0.001, 1), _f("T1", "T1", 0.5, 0.001, 100), _f("VMAX", "VMAX", 1.0, 0, 2),
    _f("VMIN", "VMIN", 0.0, 0, 2), _f("T2", "T2", 2.5, 0, 100), _f("T3", "T3", 7.5, 0.001, 100),
    _f("Dt", "Dt", 0.0, 0, 10),
), ("r", "t1", "vmax", "vmin", "t2", "t3", "dt"), _common())

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
                                 "its K3 (0)", read_as=0.0)), _ieeeg1_stages,
    "K3 = 1 - K1 - K5 - K7, the rest of the shaft (K3_rest = 1)")

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
            Dropped("K_track", 10.0, "tracking gain of iGrGen's smooth anti-windup; PSS/E's gate is exact"),
            Dropped("DELT", 0.005, "PSS/E's own time step, which iGrGen's acceleration limiter stands in for")))

HYGOV = Model("HYGOV", (
    _f("R", "R", 0.05, 0.001, 1, pslf="rperm"), _f("r", "r", 0.3, 0.001, 5, pslf="rtemp"),
    _f("Tr", "Tr", 5.0, 0.001, 100),
    _f("Tf", "Tf", 0.05, 0.001, 10), _f("Tg", "Tg", 0.5, 0.001, 10), _f("VELM", "VELM", 0.2, 1e-4, 10),
    _f("GMAX", "GMAX", 1.0, 0, 2), _f("GMIN", "GMIN", 0.0, 0, 2), _f("TW", "TW", 1.0, 0.01, 10),
    _f("At", "At", 1.2, 0.5, 2), _f("Dturb", "Dturb", 0.5, 0, 5), _f("qNL", "qNL", 0.08, 0, 0.5),
), ("rperm", "rtemp", "tr", "tf", "tg", "velm", "gmax", "gmin", "tw", "at", "dturb", "qnl"), _common())

MODELS: dict[str, Model] = {m.name: m for m in (TGOV1, IEEEG1, GGOV1, HYGOV)}


def model_named(name: str) -> Model:
    """The table of a model, by PSS/E or PSLF name (any case)."""
    model = MODELS.get(name.upper())
    if model is None:
        raise ParameterError(f"no record table for model {name!r}; the standard models are {', '.join(MODELS)}")
    return model


@dataclass(frozen=True)
class Record:
    """A governor record read from a file: its iGrGen parameter values (pu on the machine
    base), where it applies, and the fields that have no iGrGen counterpart (``extra``)."""

    model: str
    values: dict[str, float]
    bus: int
    machine_id: str
    mva: float | None
    extra: dict[str, float] = field(default_factory=dict)
    file: str = "<text>"
    line: int = 0
    bus_name: str | None = None
    kv: float | None = None


@dataclass(frozen=True)
class Written:
    """A record written: its text, where it went, and the iGrGen values it could not carry."""

    model: str
    text: str
    path: str | None
    dropped: dict[str, float]


def record_numbers(model: Model, values: Mapping[str, float],
                   extra: Mapping[str, float] | None = None) -> tuple[list[tuple[Field, float]], dict[str, float]]:
    """The fields' values in the PSS/E order from iGrGen ``values`` (names without the
    bench's ``gov.`` prefix; a parameter not given is written at its iGrGen default), and
    the dropped values. Warns (:class:`ExchangeWarning`) for a dropped sharpness or time
    step away from its default."""
    known = set(model.params)
    unknown = sorted(set(values) - known)
    if unknown:
        raise ParameterError(f"{model.name} has no parameter {', '.join(unknown)}; its parameters: {', '.join(model.params)}")
    extra = dict(extra or {})
    values = model.resolve(dict(values)) if model.resolve else values
    numbers = []
    for f in model.fields:
        if f.param is not None:
            v = float(values.get(f.param, f.default))
            if not f.lo <= v <= f.hi:  # a file its own reader would refuse is never written
                raise ParameterError(f"{model.name}.{f.param} = {v!r} is outside the range a record can state "
                                     f"({f.allowed()})" + (" (1 - K1 - K5 - K7 with K3_rest = 1)"
                                                           if f.param == "K3" and model.resolve else ""))
            if f.zero_as is not None and math.isclose(v, f.zero_as, rel_tol=1e-12):
                v = 0.0
        else:
            v = float(extra.pop(f.key, f.default))
        if not math.isfinite(v):
            raise ParameterError(f"{model.name}.{f.param or f.key} = {v}: not a finite number")
        numbers.append((f, v))
    if extra:
        raise ParameterError(f"{model.name} has no record field {', '.join(sorted(extra))} without an iGrGen counterpart")
    dropped = {d.param: float(values[d.param]) for d in model.dropped if d.param in values}
    for d in model.dropped:
        if d.default is not None and d.param in dropped and not math.isclose(dropped[d.param], d.default,
                                                                              rel_tol=1e-9):
            warnings.warn(f"{model.name}.{d.param} = {dropped[d.param]:g} is not written (default {d.default:g}): "
                          f"{d.why}", ExchangeWarning, stacklevel=3)
    return numbers, dropped


def values_from_numbers(model: Model, numbers: Mapping[str, tuple[str, str]], file: str, line: int,
                        mva: float | None) -> tuple[dict[str, float], dict[str, float]]:
    """iGrGen values and kept extras from a record's fields (PSS/E name -> (name as
    written, text)), each checked against what the iGrGen model can represent, with what
    reading them implies (:meth:`Model.read_values`: IEEEG1's K3 as stated)."""
    values, extra = {}, {}
    for f in model.fields:
        shown, text = numbers[f.key]
        try:
            v = float(text.replace("D", "E").replace("d", "e"))
        except ValueError:
            raise RecordError("not a number", file, line, shown, text, f.allowed()) from None
        if not math.isfinite(v):
            raise RecordError("not a finite number", file, line, shown, text, f.allowed())
        if f.keep:
            if f.psse == "Trate" and v != 0 and not (mva is not None and math.isclose(v, mva, rel_tol=1e-9)):
                raise RecordError(f"{model.name} on a turbine rating other than the machine base is not converted",
                                  file, line, shown, text, "0 (the machine base)" + (f" or {mva:g}" if mva else ""))
            extra[f.key] = v
            continue
        if f.choices is not None and v not in f.choices:
            raise RecordError(f"{model.name} flag not offered by the iGrGen model", file, line, shown, text, f.allowed())
        if f.param is None:
            if v != f.default:
                raise RecordError(f"the iGrGen {model.name} has no counterpart", file, line, shown, text, f.allowed())
            continue
        if f.zero_as is not None and v == 0:
            v = f.zero_as
        if not f.lo <= v <= f.hi:
            raise RecordError(f"outside the iGrGen {model.name}'s range", file, line, shown, text, f.allowed())
        values[f.param] = v
    return model.read_values(values), extra


def number_text(value: float, integer: bool = False) -> str:
    """The shortest text that reads back to the same float (integers for flags)."""
    return str(int(value)) if integer else repr(float(value))


def choose(records: list[Record], others: list[str], file: str, bus: int | None, machine_id: str | None) -> Record:
    """The one record matching ``bus``/``machine_id`` (shared by both formats)."""
    chosen = [r for r in records if (bus is None or r.bus == bus) and (machine_id is None or r.machine_id == machine_id)]
    if len(chosen) == 1:
        return chosen[0]
    models = ", ".join(MODELS)
    if not records:
        found = f"; it holds {', '.join(others)}" if others else "; it holds no record"
        raise RecordError(f"no {models} record{found}", file, None, None, None, models)
    listed = ", ".join(f"{r.model} at bus {r.bus} id {r.machine_id} (line {r.line})" for r in records)
    which = "none" if not chosen else "several"
    raise RecordError(f"{which} of its governor records match bus={bus} id={machine_id}: {listed}", file)
