"""Named candidate effects: what each is physically, where it sits in the signal path,
its parameters with bounds, and how to compose it with others into a test bench.

Every effect is a Modelica extension of a base bench: the staged test (``iGrGen.
TestBenches.StagedTest``) or the recorded-frequency bench (``FrequencyInput``).
Frequency-path blocks go between the source (or the input) and the governor, valve-side
effects swap the governor for a TG Type I variant, the transducer goes after it. A
recorded-frequency bench also has the electrical power pe (iGrGen.Machines.SwingPower on
the mechanical power, after a temperature limit; the transducer lag acts on pm only). Single
effects on the staged test have hand-written benches in the package; the rest
(combinations, the greedy second effect, effects on the recorded-frequency bench, and
calibrated results) are generated here as Modelica text.

Variants (:data:`VARIANTS`) are effects of the same physics in a slightly different form:
a load controller acting on filtered power, a rate limit on the governor's command
rather than on the valve lag. They are not first-round candidates (they would only split
the verdict between twins); the diagnosis tries them when a freed documented constant
joins their parent effect, since a constant off its documented value can imitate a
small difference of form (:mod:`.variants`). :data:`EFFECTS` holds both.

Each parameter carries an ``off`` value (the effect absent) and a ``material`` value: a
size an engineer would care about. If a fit with the effect held at its material size is
as good as the base model, the data cannot exclude the effect (it is confounded with the
base parameters, e.g. a deadband with a larger droop when every step has one size).
"""

from __future__ import annotations

from enum import StrEnum
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

from ..simulator.delayed import DELAYED_FREQUENCY

BASE_BENCH = "iGrGen.TestBenches.StagedTest"
INPUT_BENCH = "iGrGen.TestBenches.FrequencyInput"
# The standard structures of iGrGen.Governors, each with the same two benches.
STANDARD = ("TGOV1", "IEEEG1", "GGOV1", "HYGOV", "GAST")
# The benches the effects are composed into: a staged step from a source block, or a
# recorded frequency deviation (Hz) fed through the input f_dev; into TG Type I, or into a
# standard structure, where only frequency-path and output effects apply (the valve-side
# ones are TG Type I variants; the standard models carry their own valve limits).
BASES = {BASE_BENCH: "StagedTest", INPUT_BENCH: "FrequencyInput",
         **{f"iGrGen.TestBenches.{kind}{g}": f"{kind}{g}" for g in STANDARD
            for kind in ("StagedTest", "FrequencyInput")}}


class VerdictKind(StrEnum):
    """What a verdict is, whatever effect or structure it names: one named, none (nothing
    missing), ambiguous (several the data cannot tell apart), unexplained (nothing known
    explains the data). A verdict's ``effect`` or ``structure`` holds the word (a name,
    or one of the constants below, plain strings that HDF5 attributes and JSON take as
    they are); :meth:`of` tells its kind."""

    NAMED = "named"
    NONE = "none"
    AMBIGUOUS = "ambiguous"
    UNEXPLAINED = "unexplained"

    @classmethod
    def of(cls, verdict: str) -> "VerdictKind":
        """The kind of a verdict's effect or structure: a name is NAMED."""
        return cls(verdict) if verdict in {k.value for k in cls} - {"named"} else cls.NAMED


NONE, AMBIGUOUS, UNEXPLAINED = (VerdictKind.NONE.value, VerdictKind.AMBIGUOUS.value,
                                VerdictKind.UNEXPLAINED.value)  # the words, as a verdict's effect holds them
BASE = "none"  # the label of the candidate without an effect (the base model), in rankings and fits


@dataclass(frozen=True)
class EffectParameter:
    name: str  # FMU parameter name in the bench
    label: str
    unit: str
    min: float
    max: float
    off: float
    material: float
    scale: str = "linear"  # "log" for ranges spanning decades


@dataclass(frozen=True)
class Effect:
    name: str
    title: str
    site: str  # "frequency" | "valve" | "output"
    bench: str  # hand-written single-effect bench
    parameters: tuple[EffectParameter, ...]
    physics: str  # what it is, for the report
    signature: str  # how it shows in the residuals, for the report
    relative: bool = False  # a freed documented constant: bounds, off and material are factors of its value
    variant_of: str | None = None  # the catalogue effect this one is a variant of


def _documented(name: str, label: str) -> Effect:
    """A documented constant freed: searched from 0.25 to 4 times the documented value
    (log scale), material when off by half again (x1.5 or /1.5)."""
    return Effect(f"doc_{label}", f"documented {label} is wrong", "documented", BASE_BENCH,
                  (EffectParameter(name, label, "s", 0.25, 4.0, 1.0, 1.5, "log"),),
                  f"the plant documentation's {label} is not the plant's: the model has the right structure, "
                  "one constant wrong", f"the response's shape is off where {label} acts, with no effect's signature",
                  relative=True)


CATALOGUE: dict[str, Effect] = {e.name: e for e in [
    Effect("deadband", "intentional deadband on the frequency deviation", "frequency",
           "iGrGen.TestBenches.StagedTestDeadband",
           (EffectParameter("db.db", "deadband", "Hz", 0.0, 0.1, 0.0, 0.03),),
           "deviations smaller than the band are ignored; larger ones act reduced by it",
           "responses do not scale with the step size: small steps respond less than in proportion"),
    Effect("rate_limit", "valve rate limits (opening, closing)", "valve",
           "iGrGen.TestBenches.StagedTestRateLimit",
           (EffectParameter("gov.rate_open", "opening rate", "pu/s", 0.001, 0.2, 0.2, 0.01, "log"),
            EffectParameter("gov.rate_close", "closing rate", "pu/s", 0.001, 0.2, 0.2, 0.01, "log")),
           "the valve cannot move faster than its actuator allows, possibly differently each way",
           "constant-slope ramps; rises and falls at different speeds (up/down asymmetry)"),
    Effect("delay", "transport delay", "frequency", "iGrGen.TestBenches.StagedTestDelay",
           (EffectParameter("dly.T", "delay", "s", 0.01, 3.0, 0.01, 0.8, "log"),),
           "the governor acts on the frequency deviation late (measurement, communication)",
           "the response starts late and stays shifted in time (a lag in the cross-correlation)"),
    Effect("backlash", "backlash on the valve position", "valve", "iGrGen.TestBenches.StagedTestBacklash",
           (EffectParameter("gov.backlash", "backlash", "pu", 0.0, 0.05, 0.0, 0.01),),
           "play between governor and valve: a reversal moves the governor through the play first",
           "part of the response is missing, and after a return step the power does not come back"),
    Effect("load_controller", "slow load controller pulling power back", "valve",
           "iGrGen.TestBenches.StagedTestLoadController",
           (EffectParameter("gov.K_lc", "load-loop gain", "1/s", 1e-4, 0.05, 1e-4, 0.01, "log"),),
           "an outer loop integrates the power error and drags the output back to its set-point",
           "the power withdraws slowly after the step instead of settling"),
    Effect("measurement_lag", "lagging power transducer", "output", "iGrGen.TestBenches.StagedTestMeasurementLag",
           (EffectParameter("meas.T", "transducer lag", "s", 0.01, 5.0, 0.01, 0.8, "log"),),
           "the recorded power is a filtered version of the mechanical power",
           "the measured response is smoother and later than the model, most at the step"),
    Effect("output_limit", "output limit above the dispatch point (temperature control)", "output",
           "iGrGen.TestBenches.StagedTestOutputLimit",
           (EffectParameter("lim.headroom", "headroom above p_ref", "pu", 0.005, 0.5, 0.5, 0.03, "log"),),
           "near its rating a gas turbine enters temperature-limit control and stops short of what droop asks",
           "power-raising responses flatten at a ceiling; power-lowering ones are whole"),
    # The documented time constants (pmax and pmin are not freed: a factor of pmin = 0 is
    # nothing, and a ceiling below pmax is the output limit above).
    *(_documented(f"gov.{c}", c) for c in ("Tc", "T3", "T4", "T5")),
]}

VARIANTS: dict[str, Effect] = {e.name: e for e in [
    Effect("load_controller_filtered", "slow load controller acting on filtered power", "valve",
           "iGrGen.TestBenches.StagedTestLoadControllerFiltered",
           (EffectParameter("gov.K_lc", "load-loop gain", "1/s", 1e-4, 0.05, 1e-4, 0.01, "log"),
            EffectParameter("gov.T_f", "measurement filter", "s", 0.5, 100.0, 0.5, 10.0, "log")),
           "the load controller integrates the power error as its filtered measurement shows it",
           "the withdrawal starts late and rounded instead of at once", variant_of="load_controller"),
    Effect("rate_limit_command", "rate limits on the governor's command", "valve",
           "iGrGen.TestBenches.StagedTestRateLimitCommand",
           (EffectParameter("gov.rate_open", "opening rate", "pu/s", 0.001, 0.2, 0.2, 0.01, "log"),
            EffectParameter("gov.rate_close", "closing rate", "pu/s", 0.001, 0.2, 0.2, 0.01, "log")),
           "the power command is ramp-limited before the governor lag, not the valve's own motion",
           "ramps with rounded ends: the lag smooths the ramped command", variant_of="rate_limit"),
]}
EFFECTS: dict[str, Effect] = {**CATALOGUE, **VARIANTS}


def variants_of(effect: str) -> list[str]:
    return [name for name, e in VARIANTS.items() if e.variant_of == effect]


# The valve-side effects TGTypeIValveEffects combines (the variants have a governor each).
_VALVE = {"rate_limit", "backlash", "load_controller"}
_VARIANT_GOVERNORS = {"load_controller_filtered": "TGTypeILoadControlFiltered",
                      "rate_limit_command": "TGTypeIRateLimitCommand"}


def effect_parameters(effects: Sequence[str]) -> tuple[EffectParameter, ...]:
    return tuple(p for name in effects for p in EFFECTS[name].parameters)


def check_effects(effects: Sequence[str]) -> tuple[str, ...]:
    unknown = [e for e in effects if e not in EFFECTS]
    if unknown:
        raise ValueError(f"unknown effect(s) {unknown}; catalogue: {', '.join(EFFECTS)}")
    if len(set(effects)) != len(effects):
        raise ValueError(f"effect listed twice in {list(effects)}")
    variants = [e for e in effects if e in VARIANTS]
    valve = [e for e in effects if e in _VALVE or e in VARIANTS]
    if variants and len(valve) > 1:
        raise ValueError(f"{variants[0]} is a governor of its own and does not combine with {valve}")
    # a canonical order makes one bench per set of effects
    return tuple(e for e in EFFECTS if e in effects)


def check_base(model: str) -> str:
    if model not in BASES:
        raise ValueError(f"diagnose composes effects into the benches {', '.join(BASES)}; {model} is none of "
                         "them (an experiment on another model can be calibrated, not diagnosed)")
    return model


def governor(base: str) -> str:
    """The governor class a base bench holds."""
    return BASES[check_base(base)].removeprefix("StagedTest").removeprefix("FrequencyInput") or "TGTypeI"


def is_staged(base: str) -> bool:
    return BASES[check_base(base)].startswith("StagedTest")


def composable(effect: str, base: str) -> bool:
    """Whether ``effect`` can be composed into ``base``: every effect into TG Type I's
    benches; into a standard structure's, those on the frequency path or the output."""
    return governor(base) == "TGTypeI" or EFFECTS[effect].site in ("frequency", "output")


def bench_name(effects: Sequence[str], base: str = BASE_BENCH) -> str:
    """Class name of the bench for a set of effects on ``base`` (hand-written for zero or
    one effect on the staged test, generated into iGrGen.Diagnosed otherwise)."""
    effects = tuple(e for e in check_effects(effects) if not EFFECTS[e].relative)  # freed constants: same bench
    if not effects:
        return check_base(base)
    _check_composable(effects, base)
    if len(effects) == 1 and base == BASE_BENCH:
        return EFFECTS[effects[0]].bench
    return f"iGrGen.Diagnosed.{BASES[check_base(base)]}" + "".join(camel(e) for e in effects)


def _check_composable(effects: Sequence[str], base: str) -> None:
    wrong = [e for e in effects if not composable(e, base)]
    if wrong:
        raise ValueError(f"{', '.join(wrong)} cannot be composed into {base}: valve-side effects are TG Type I "
                         f"variants ({governor(base)} has its own valve limits among its parameters)")


def is_generated(bench: str) -> bool:
    return bench.startswith("iGrGen.Diagnosed.")


def camel(name: str) -> str:
    return "".join(part.capitalize() for part in name.split("_"))


def _modifiers(values: Mapping[str, float], prefix: str) -> str:
    own = {k[len(prefix) + 1:]: v for k, v in values.items() if k.startswith(prefix + ".")}
    return "(" + ", ".join(f"{k} = {v:.10g}" for k, v in own.items()) + ")" if own else ""


def bench_source(effects: Sequence[str], class_name: str, *, values: Mapping[str, float] | None = None,
                 description: str = "", base: str = BASE_BENCH) -> str:
    """Modelica text of a bench: ``base`` with ``effects`` composed in, and ``values``
    (FMU names such as ``gov.R``) as modifiers, e.g. calibrated parameters."""
    effects = tuple(e for e in check_effects(effects) if not EFFECTS[e].relative)
    _check_composable(effects, base)
    values = dict(values or {})
    short = class_name.rsplit(".", 1)[-1]
    within = class_name.rsplit(".", 1)[0] if "." in class_name else ""
    valve = [e for e in effects if e in _VALVE]
    variant = [e for e in effects if e in _VARIANT_GOVERNORS]
    if governor(base) != "TGTypeI":
        gov_class = governor(base)
    elif variant:
        gov_class = _VARIANT_GOVERNORS[variant[0]]
    elif not valve:
        gov_class = "TGTypeI"
    elif len(valve) == 1:
        gov_class = {"rate_limit": "TGTypeIRateLimit", "backlash": "TGTypeIBacklash",
                     "load_controller": "TGTypeILoadControl"}[valve[0]]
    else:
        gov_class = "TGTypeIValveEffects"
    if gov_class == "TGTypeIValveEffects" and "backlash" not in effects:
        values.setdefault("gov.T_bl", 1e-3)  # without backlash the valve should simply follow
    kind = "staged test" if is_staged(base) else "recorded-frequency bench"
    lines = [f"within {within};" if within else "within;",
             f'model {short} "{description or kind + " with " + (", ".join(effects) or "no effect")}"']
    connects = []
    # A delay acts on a known input, so it is exact (Effects.TransportDelay): a staged test's
    # step moves its switching instants, a recorded event is read at t - T (f_dev_delayed,
    # filled by the runner). It commutes with the static deadband that may follow it.
    delayed = "delay" in effects
    if delayed:
        lines.append(f"  Effects.TransportDelay dly{_modifiers(values, 'dly')};")
    if is_staged(base):
        own = _modifiers(values, "src")
        mods = ", ".join(m for m in ("t_delay = dly.T" if delayed else "", own[1:-1]) if m)
        lines.append(f"  Sources.FrequencyStep src{'(' + mods + ')' if mods else ''};")
        path = "src.y"
    else:  # as TestBenches.FrequencyInput: the recorded deviation in Hz, on the f_nom base
        f_nom = values.pop("f_nom", 50.0)
        lines += [f'  parameter Types.Frequency f_nom(min=1) = {f_nom:.10g} "frequency base";',
                  '  input Types.Frequency f_dev "measured frequency minus nominal";',
                  '  input Types.FrequencyRate rocof "rate of change of the measured frequency (Hz/s)";',
                  f"  Machines.SwingPower mach{_modifiers(values, 'mach')};"]
        if delayed:
            lines.append(f'  input Types.Frequency {DELAYED_FREQUENCY} "f_dev at t - dly.T, as the governor receives it '
                         '(the runner fills it from f_dev)";')
        path = None
    heard = DELAYED_FREQUENCY if delayed else "f_dev"

    def feed(block: str) -> None:
        connects.append(f"connect({path}, {block});" if path else f"{block}.signal = -{heard} / f_nom;")

    if "deadband" in effects:  # its band in Hz on the test's own frequency base
        own = _modifiers({k: v for k, v in values.items() if k != "db.f_nom"}, "db")
        if not is_staged(base):  # a name of its own: in db's modifier, f_nom would be db's own
            lines.append('  final parameter Types.Frequency f_base = f_nom "the deadband\'s frequency base";')
        f_base = "src.f_nom" if is_staged(base) else "f_base"
        lines.append(f"  Effects.Deadband db(f_nom = {f_base}{', ' + own[1:-1] if own else ''});")
        feed("db.u")
        path = "db.y"
    lines.append(f"  Governors.{gov_class} gov{_modifiers(values, 'gov')};")
    feed("gov.dw")
    out = "gov.pm"
    if "output_limit" in effects:  # counted from the governor's dispatch point
        own = _modifiers(values, "lim")
        lines.append(f"  Effects.OutputLimit lim(p_ref = gov.p_ref{', ' + own[1:-1] if own else ''});")
        connects.append(f"connect({out}, lim.u);")
        out = "lim.y"
    if not is_staged(base):  # the machine takes the mechanical power (after a temperature limit)
        connects += [f"connect({out}, mach.pm);", "mach.dw.signal = f_dev / f_nom;",
                     "mach.dwdt.signal = rocof / f_nom;"]
        if governor(base) == "GGOV1":
            connects.append("connect(mach.pe, gov.pelec);")
    elif governor(base) == "GGOV1":  # a staged test's stiff grid: electrical power is mechanical
        connects.append("connect(gov.pm, gov.pelec);")
    if "measurement_lag" in effects:
        lines.append(f"  Effects.MeasurementLag meas{_modifiers(values, 'meas')};")
        connects.append(f"connect({out}, meas.u);")
        out = "meas.y"
    out += ".signal"
    lines.append('  output Types.PerUnit pm "mechanical power as recorded (pu)";')
    if not is_staged(base):
        lines.append('  output Types.PerUnit pe "electrical power at the terminals (pu)";')
    lines.append("equation")
    lines += [f"  {c}" for c in connects]
    lines.append(f"  pm = {out};")
    if not is_staged(base):  # the transducer lag acts on pm only (not composed on pe)
        lines.append("  pe = mach.pe.signal;")
    named = ", ".join(effects) or "no effect"
    lines += [f'  annotation(Documentation(info="<html><p>The {kind} ({base}) with {named}, composed from '
              "iGrGen.Effects and iGrGen.Governors by rapid-cosim's discrepancy workflow "
              '(rapid_cosim.diagnose.catalogue).</p></html>",',
              '    revisions="<html><ul><li>Generated by rapid-cosim: rerun the diagnosis rather than edit it.'
              '</li></ul></html>"));',
              f"end {short};"]
    return "\n".join(lines) + "\n"


def write_bench(package: str | Path, effects: Sequence[str], class_name: str, *,
                values: Mapping[str, float] | None = None, description: str = "", register: bool = True,
                base: str = BASE_BENCH) -> Path:
    """Write the bench of ``effects`` as ``class_name`` (in ``iGrGen.Diagnosed``) into
    ``package``. An unchanged file is not rewritten; ``register`` lists it in
    ``package.order``."""
    path = Path(package) / "Diagnosed" / f"{class_name.rsplit('.', 1)[1]}.mo"
    text = bench_source(effects, class_name, values=values, description=description, base=base)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    if register:
        order = path.parent / "package.order"
        lines = [line.strip() for line in order.read_text().splitlines() if line.strip()] if order.exists() else []
        if path.stem not in lines:
            order.write_text("\n".join(lines + [path.stem]) + "\n")
    return path
