"""What a record table is: the fields of a PSS/E and PSLF record and the iGrGen parameter
each one carries, shared by :mod:`.psse_dyr` and :mod:`.pslf_dyd`; the tables of the
standard models themselves are in :mod:`.layouts`.

Why a table: both formats are positional lists of numbers whose meaning is fixed by the
simulator's model library, and a wrong position is a silent error. Keeping the mapping in
one place, with the iGrGen default and range of every parameter (checked against
``modelica/iGrGen/Governors/*.mo`` by ``tests/test_exchange.py``), makes both formats agree
by construction.

Conversions (the same for both formats)
---------------------------------------
* **Bases.** The iGrGen governors are in pu on the machine's MVA base, as the PSS/E
  Model Library and PSLF give them: values are written and read **unchanged**. A ``.dyr``
  record carries no base (PSS/E takes the machine's MBASE from the ``.raw`` generator
  record); a ``.dyd`` record states it as ``mva=``. GGOV1's ``Trate`` (PSS/E's turbine rating,
  MW; also the deadband layouts' last field) is written 0, which PSS/E reads as "the
  machine base"; a record with another ``Trate``
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
* **Layouts of one block.** A block may be written in more than one layout: TGOV1 with a
  deadband is the record TGOV1D (TGOV1's fields, then ``dbH``, ``dbL`` and ``Trate``). The
  plain layout names the parameter it cannot carry with the layout that can
  (``Dropped.layout``), and a writer takes that layout where the value differs from the
  plain one's (:func:`layout_for`); a plain record read means the plain value (no
  deadband). One parameter may fill two fields with a sign (``Field.scale``: ``dbL`` is
  ``-db``); read back, they must agree (an asymmetric band is refused, not averaged).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Callable, Mapping

from ..errors import ParameterError, RecordError


class NoLayout(ParameterError):
    """A format has no layout for what a record carries (PSLF for a deadband): the other
    format's record carries it."""


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
    scale: float = 1.0  # the field states scale x the parameter (dbL = -db)

    @property
    def key(self) -> str:
        """The field's name in both formats' dicts: PSS/E's, else PSLF's."""
        return self.psse or self.pslf

    def allowed(self) -> str:
        if self.choices is not None:
            return " or ".join(f"{c:g}" for c in self.choices)
        if self.param is None and not self.keep:
            return f"{self.default:g} (no iGrGen counterpart)"
        lo, hi = sorted((self.lo * self.scale, self.hi * self.scale))
        text = f"{lo:g} to {hi:g}"
        return f"0 or {text}" if self.zero_as is not None else text


@dataclass(frozen=True)
class Dropped:
    """An iGrGen parameter no record field carries, and why.

    ``operating``: an operating point, which the grid simulator sets from its power flow
    for each event; it is no part of a record, so a fit may hold it at another value per
    test. ``read_as``: the value a record read back means, where the parameter chooses
    how other fields are used (IEEEG1's ``K3_rest`` 0: K3 as the record states it).
    ``layout``: the layout whose fields carry the parameter (TGOV1's ``db``: TGOV1D); a
    record of this layout means its ``default``."""

    param: str
    default: float | None  # None: nothing to warn against when it is not written
    why: str
    operating: bool = False
    read_as: float | None = None
    layout: str | None = None
    newer: bool = False  # added to the block later: a bench built before has none (an older archive's)


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
    family: str = ""  # the iGrGen block this layout writes (TGOV1D: TGOV1); "": the model's own name
    pslf: bool = True  # PSLF has the layout (a .dyd record of it)

    @property
    def block(self) -> str:
        """The iGrGen block (and structure) the layout is a record of."""
        return self.family or self.name

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

    @property
    def required_params(self) -> tuple[str, ...]:
        """The record's parameters every bench of the block has (not those added later,
        :attr:`Dropped.newer`, which an older archive's bench lacks: the plain value)."""
        newer = {d.param for d in self.dropped if d.newer}
        return tuple(p for p in self.record_params if p not in newer)

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
        # a TGOV1 record states no deadband: where the context holds one, the record's plain
        # value replaces it (elsewhere the bench's default is that value; a bench built before
        # the deadband has no such parameter to set)
        absent = {d.param: d.default for d in self.dropped if d.layout is not None and prefix + d.param in context}
        stated = {prefix + k: float(v) for k, v in {**absent, **self.read_values(values)}.items()}
        covered = {prefix + f.param for f in self.fields if f.param} | set(stated)
        return {**{k: v for k, v in context.items() if k not in covered}, **stated}

    @property
    def psse_fields(self) -> tuple[Field, ...]:
        return tuple(f for f in self.fields if f.psse is not None)

    def by_pslf(self) -> dict[str, Field]:
        return {f.pslf: f for f in self.fields if f.pslf is not None}


def layout_for(model: Model, values: Mapping[str, float], layouts: Mapping[str, Model]) -> Model:
    """The layout that carries ``values``: ``model``, or the layout its dropped parameter
    names where the value is not the plain one (TGOV1 with a deadband: TGOV1D)."""
    for d in model.dropped:
        if d.layout is not None and d.param in values and not math.isclose(float(values[d.param]), d.default,
                                                                             rel_tol=0, abs_tol=0):
            return layouts[d.layout]
    return model


@dataclass(frozen=True)
class Record:
    """A governor record read from a file: its iGrGen parameter values (pu on the machine
    base), where it applies, and the fields that have no iGrGen counterpart (``extra``).
    ``model`` is the layout as written (TGOV1D), ``family`` its iGrGen block (TGOV1)."""

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
    family: str = ""  # the iGrGen block (and structure) of the layout; "": model

    @property
    def block(self) -> str:
        return self.family or self.model


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
    for d in model.dropped:
        if d.layout is not None and d.param in values and float(values[d.param]) != d.default:
            raise ParameterError(f"{model.name} cannot carry {d.param} = {values[d.param]!r} (the {d.layout} "
                                 f"record does)")
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
            v = f.scale * v + 0.0  # + 0.0: no negative zero in a file
        else:
            v = float(extra.pop(f.key, f.default))
        if not math.isfinite(v):
            raise ParameterError(f"{model.name}.{f.param or f.key} = {v}: not a finite number")
        numbers.append((f, v))
    if extra:
        raise ParameterError(f"{model.name} has no record field {', '.join(sorted(extra))} without an iGrGen counterpart")
    dropped = {d.param: float(values[d.param]) for d in model.dropped if d.param in values and d.layout is None}
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
        v = v / f.scale + 0.0
        if not f.lo <= v <= f.hi:
            raise RecordError(f"outside the iGrGen {model.name}'s range", file, line, shown, text, f.allowed())
        if f.param in values and not math.isclose(values[f.param], v, rel_tol=1e-9, abs_tol=1e-15):
            first = next(g for g in model.fields if g.param == f.param)
            raise RecordError(f"{f.key} must be {f.scale / first.scale:g} x {first.key} (the iGrGen {model.block} "
                              f"has one {f.param}: an asymmetric band is not modelled)", file, line, shown, text,
                              f"{f.scale * values[f.param]:.6g}")
        values[f.param] = v
    return model.read_values(values), extra


def number_text(value: float, integer: bool = False) -> str:
    """The shortest text that reads back to the same float (integers for flags)."""
    return str(int(value)) if integer else repr(float(value))


@dataclass(frozen=True)
class Other:
    """A record of a model no table reads (a GENROU, a WSIEG1), where it applies."""

    model: str
    bus: int | None
    machine_id: str | None
    line: int

    def __str__(self) -> str:
        return f"{self.model} (line {self.line})"


# Turbine-governor models of the PSS/E and PSLF libraries (and PowerWorld's deadband
# layouts): a record of one of these at the machine's bus and id is its governor, one that
# no table reads. Machines, exciters and stabilisers share the bus and id and are not.
GOVERNOR_MODELS = frozenset(name.upper() for name in (
    "TGOV1", "TGOV1D", "TGOV1N", "TGOV1NDB", "TGOV2", "TGOV3", "TGOV4", "TGOV5", "IEEEG1", "IEEEG1D", "IEEEG2",
    "IEEEG3", "IEESGO", "GAST", "GASTD", "GAST2A", "GASTWD", "GASTPTI", "GGOV1", "GGOV1D", "GGOV2", "GGOV3",
    "HYGOV", "HYGOVD", "HYGOV2", "HYGOV2D", "HYGOV4", "HYGOVM", "HYGOVT", "HYGOVR", "HYG3", "WSIEG1", "WEHGOV",
    "WESGOV", "WPIDHY", "WSHYDD", "WSHYGP", "DEGOV", "DEGOV1", "DEGOV1D", "CRCMGV", "IVOGO", "PIDGOV", "PIDGOVD",
    "TURCZT", "URGS3T", "BBGOV1", "H6B", "H6BD", "G2WSCC", "GPWSCC", "W2301", "LM2500", "LM6000", "CCBT1", "CCST3",
    "TGOV1DB", "HYGOVDB"))


class UnsupportedRecord(RecordError):
    """The machine's governor record is of a model this toolkit does not carry: a fleet
    lists its unit as not supported rather than stopping."""

    def __init__(self, other: Other, file: str, supported: str):
        self.model = other.model
        super().__init__(f"the record on file for bus {other.bus} id {other.machine_id} is {other.model}: not "
                         "supported", file, other.line, None, None, supported)


def choose(records: list[Record], others: list[Other], file: str, bus: int | None, machine_id: str | None,
           supported: str, bad: list[tuple[Other, RecordError]] = ()) -> Record:
    """The one record matching ``bus``/``machine_id`` (shared by both formats); ``supported``
    names the layouts read, for the error. Where none matches but a record of another
    model does, that is said (:class:`UnsupportedRecord`); where the machine's record is
    one that could not be read (``bad``), its own error is raised, and other machines' bad
    records are theirs."""
    def here(r) -> bool:
        return (bus is None or r.bus == bus) and (machine_id is None or r.machine_id == machine_id)

    mine = [e for o, e in bad if here(o)]
    if mine and (bus is not None or machine_id is not None or not records):
        raise mine[0]

    chosen = [r for r in records if here(r)]
    if len(chosen) == 1:
        return chosen[0]
    models = supported
    theirs = [o for o in others if o.model.upper() in GOVERNOR_MODELS and (bus is not None or machine_id is not None)
              and here(o)]
    if not chosen and len(theirs) == 1:
        raise UnsupportedRecord(theirs[0], file, models)
    if not records:
        found = f"; it holds {', '.join(map(str, others))}" if others else "; it holds no record"
        raise RecordError(f"no {models} record{found}", file, None, None, None, models)
    listed = ", ".join(f"{r.model} at bus {r.bus} id {r.machine_id} (line {r.line})" for r in records)
    which = "none" if not chosen else "several"
    raise RecordError(f"{which} of its governor records match bus={bus} id={machine_id}: {listed}", file)
