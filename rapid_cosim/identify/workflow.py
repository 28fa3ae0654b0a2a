"""One identification per unit: the explanation and the deliverable, from one selection
with one noise model.

* **The explanation** is the discrepancy workflow on TG Type I (the base of the effect
  catalogue): which effects the unit has, adequate or not (:mod:`rapid_cosim.diagnose`).
* **The deliverable** is a standard record. Every standard structure the unit allows is
  calibrated by the same whitened multistart least squares and judged by the same
  computed null (:func:`rapid_cosim.structures.select.select_structure`); a structure
  with optional parts (IEEEG1's valve rates ``Uo``/``Uc``) is also fitted with each set
  of them free (both, the opening alone, the closing alone: a rate the tests never reach
  is left at its default, not at a value the data cannot see; each screened from the
  structure's optimum first and searched whole only where the screen comes within reach,
  :mod:`rapid_cosim.structures.calibrations`), and the best of those fits is kept only
  where it wins by the selection threshold (the data call for them). Each record's fidelity is stated per test in noise units beside the
  explanation's, with what it cannot carry in plain words.
* **The recommendation** follows the criterion: the first record by BIC (with its optional
  parts where they won). A simpler record is recommended only where it ties with it
  (within the selection threshold), carries what the explanation found, and is not held
  by its bounds or outside the noise where the first is neither; both are said. A record
  that is not within the noise on every test is still recommended when it is first, and
  said to be so.
* **For its report** (:mod:`.deliver`): the held-out tests on the recommended record's
  bench and the explanation's diagnosis, written into the work folder; the records and
  the report are written from them by :func:`rapid_cosim.api.identify`.

Both parts estimate the recorder's noise model from the same quiet stretches
(:func:`rapid_cosim.noise.campaign_noise` is deterministic in its data), so they whiten
the same way.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from scipy.stats import chi2

from ..calibration import RunOptions
from ..compiler.source import ModelSource
from ..diagnose.context import METHOD
from ..diagnose.selection import THRESHOLD
from ..structures.structure import Structure, on_structure
from ..structures.identifiability import REL_WEAK as WEAK_SE
from ..structures.select import Calibrations, StructureFit, StructureVerdict, select_structure
from ..diagnose.null import KeptReplicates
from ..diagnose.result import Diagnosis
from ..diagnose.workflow import DiagnoseOptions, diagnose, split_holdout
from ..exchange import MODELS
from ..errors import CheckFailed
from ..experiment import Experiment
from ..fitting.engine import EngineSpec
from ..noise import NoiseFit, campaign_noise
from .check import check_unit, say, unsaid
from .deliver import write_configs
from .result import CARRIES, NEUTRAL, Explanation, Identification, StandardRecord, TestFidelity, cannot_carry
from .unit import Unit


def identify(unit: Unit | str | Path, *, workdir: str | Path, seed: int = 1, engine: EngineSpec = EngineSpec(),
             source: ModelSource = ModelSource(), log: Callable[[str], None] = print) -> Identification:
    """The unit's explanation, each standard record's calibration and fidelity, and the
    recommended record (see the module docstring)."""
    t0 = time.perf_counter()
    check = check_unit(unit.path if isinstance(unit, Unit) else unit, source=source)
    if not check.ok:  # every problem of the unit's files at once, before the first fit
        raise CheckFailed(f"{check.unit.path if check.unit else unit}", check.findings)
    unit = unit if isinstance(unit, Unit) else check.unit
    structures = check.structures
    training, heldout = split_holdout(check.experiments, unit.holdout)
    say(unsaid(check.notes, check.experiments))  # once: the story says the recordings' own lines
    workdir = Path(workdir)
    log(f"identifying {unit.name}: {len(training)} training and {len(heldout)} held-out experiments")
    fitted_noise = campaign_noise([*training, *heldout])  # one noise model for both parts
    kept = KeptReplicates()  # and one set of its replicates, where the parts' tests are the same
    options = RunOptions(method=METHOD, seed=seed, engine=engine)  # the package's own method: nothing to check
    # the standard records' fits do not depend on the explanation: on local workers they
    # start now, on a pool of their own, and fill the cores the explanation leaves idle
    calibrations = None
    try:
        calibrations = Calibrations(delivery_candidates(structures), training, fitted_noise, options,
                                    workdir / "records", source=source, start=True)
        log("the explanation (TG Type I and the effect catalogue):")
        explanation = diagnose(training, heldout, workdir=workdir / "explanation",
                               options=DiagnoseOptions(seed=seed, engine=engine, write_model=False),
                               source=source, log=log, noise_fits=fitted_noise, kept=kept)
        log(f"  {explanation.named.verdict}")
        log("the standard records:")
        d = deliver(structures, training, heldout, explanation, workdir=workdir / "records", options=options,
                    source=source, log=log, fitted_noise=fitted_noise, kept=kept, calibrations=calibrations)
    finally:  # stopped on any way out: an interrupted record's archive is resumed by the next run
        if calibrations is not None:
            calibrations.close()
    result = Identification(unit=unit.name, mva=unit.mva, bus=unit.bus, machine_id=unit.machine_id,
                            training=[e.name for e in training], heldout=[e.name for e in heldout],
                            explanation=_explanation(explanation), records=d.records, recommended=d.recommended,
                            reason=d.reason, tied_with=d.tied_with, ties=d.ties, structure_verdict=d.verdict.structure,
                            seconds=0.0,
                            recordings={e.name: e.recording.summary() for e in (*training, *heldout)})
    result.diagnosis = str(explanation.save(workdir / "explanation")[0])
    if d.recommended is not None:  # the held-out tests on the record's bench, as the selection predicted them
        fit = result.record(d.recommended).fit
        held = on_structure(next(s for s in d.candidates if s.name == fit), heldout, fitted_noise)
        result.heldout_configs = [str(p) for p in write_configs(held, workdir / "records" / f"{fit}-heldout")]
    result.seconds = time.perf_counter() - t0
    return result


@dataclass
class Delivery:
    """The deliverable part of an identification: the selection over the standard
    structures (each also with its optional parts free), the record kept of each, the
    recommendation, and the noise fit the selection whitened with."""

    verdict: StructureVerdict
    records: list[StandardRecord]
    recommended: str | None
    reason: str
    candidates: list[Structure]
    fitted_noise: dict[str, NoiseFit]  # per test name (campaign_noise)
    tied_with: str | None = None  # the first by BIC, where a simpler record tied with it is recommended
    ties: list[str] = field(default_factory=list)  # simpler records tying with the first, recommended or not


def deliver(structures: Sequence[Structure], training: Sequence[Experiment], heldout: Sequence[Experiment],
            explanation=None, *, workdir: str | Path, options: RunOptions, source: ModelSource = ModelSource(),
            log: Callable[[str], None] = print,
            fitted_noise: dict | None = None, kept: KeptReplicates | None = None,
            calibrations: Calibrations | None = None) -> Delivery:
    """Every standard record by identify's rules (optional parts kept only where they win
    by the threshold; the record the criterion prefers recommended, a simpler one only in
    a tie; a structure no
    grid simulator's record holds, TG Type I, is ranked but gets no record). ``identify``
    gives it the explanation, whose effects say what each record cannot carry;
    ``rapid-cosim structures`` runs this part alone (no explanation). ``calibrations``:
    those of :func:`delivery_candidates`, started before."""
    candidates = delivery_candidates(structures)
    fitted_noise = fitted_noise or campaign_noise([*training, *heldout])  # kept to predict the held-out tests
    verdict = select_structure(candidates, training, heldout, workdir=workdir, options=options,
                               source=source, fitted_noise=fitted_noise, log=log, kept=kept,
                               calibrations=calibrations)
    fits = {f.name: f for f in verdict.ranking}
    records = [_record(s, fits, explanation) for s in structures if s.name in MODELS]  # what a record can hold
    recommended, reason, tied_with, ties = _recommend(records)
    log(f"  recommended: {recommended or 'none'} ({reason})")
    return Delivery(verdict, records, recommended, reason, candidates, fitted_noise, tied_with, ties)


def delivery_candidates(structures: Sequence[Structure]) -> list[Structure]:
    """What the deliverable fits: each structure, and each with its optional parts free."""
    return [*structures, *(v for s in structures for v in s.optional_variants())]


def _record(structure: Structure, fits: dict[str, StructureFit], explanation: Diagnosis | None) -> StandardRecord:
    """The structure's kept fit: with the set of its optional parts that fits best by BIC,
    free only if that wins by the threshold."""
    plain = fits[structure.name]
    variants = [fits[v.name] for v in structure.optional_variants() if v.name in fits]
    freed = min(variants, key=lambda f: f.bic) if variants else None  # the parts the data call for
    use = freed if freed is not None and freed.bic <= plain.bic - THRESHOLD else plain
    effects = list(explanation.named.effects) if explanation is not None else []
    open_ = [e for e in (explanation.named.not_excluded if explanation is not None else []) if e not in effects]
    missing = cannot_carry(structure.name, effects, estimated=list(use.parameters), fixed=structure.fixed)
    explained = {t.test: t for t in explanation.adequacy.after.tests} if explanation is not None else {}
    per_test = {name: TestFidelity(t.rmse_over_noise, t.variance_ratio, t.p_holm, t.adequate,
                                   explained[name].rmse_over_noise if name in explained else None)
                for name, t in use.tests.items()}
    relative_se = use.identifiability.relative_se_by_name if use.identifiability else {}
    failing = [n for n, t in per_test.items() if not t.adequate]
    clauses = ["within the noise on every test" if use.adequate else
               f"not within the noise on {', '.join(failing)} (pooled variance ratio {use.variance_ratio:.2f})"]
    best = {e: min((fits[v.name].bic for v in structure.optional_variants() if v.name in fits
                    and structure.freed_effect(v.name) == e), default=None) for e in structure.effects}
    kept = _Kept(structure.freed_effect(use.name), plain.bic, best)
    undetermined = [e for e in structure.effects if e != kept.effect and (e in open_ or e in missing)]
    moved = {e: w for e, w in _moved_by(structure, fits, kept.effect).items() if e not in undetermined}
    clauses += _carrying(structure, missing, open_, kept, use.parameters, relative_se, moved=list(moved))
    clauses += moved.values()
    undetermined += moved
    swaps = [f"{a} and {b}" for a, b, _ in (use.identifiability.exchanges if use.identifiability else ())]
    if swaps:
        clauses.append(f"the tests fit {', '.join(swaps)} either way round: which is which is not the data's to say")
    return StandardRecord(model=structure.name, fit=use.name, optional_freed=use is freed,
                          parameters=use.parameters, n_estimated=use.n_estimated, bic=use.bic,
                          adequate=use.adequate, variance_ratio=use.variance_ratio, tests=per_test,
                          cannot_carry=missing, words="; ".join(clauses), archive=use.archive,
                          at_bounds=use.at_bounds, relative_se=relative_se, cautions=clauses[1:],
                          freed_effect=kept.effect, undetermined=undetermined)


MOVED = 0.05  # a relative change in a kept parameter that a record's user would see (a droop 5 % off)
LEANING = 0.05  # the likelihood-ratio test's level at which the data lean towards a part they do not decide


def _moved_by(structure: Structure, fits: dict[str, StructureFit], kept: str | None) -> dict[str, str]:
    """Effects whose parts were not kept, but whose freed fit is better than the plain one by
    a likelihood-ratio test at LEANING and moves a parameter the plain fit determines by more
    than MOVED and two of its standard errors: the data lean towards the effect without
    deciding it, and the record's values depend on the choice (a single event's droop
    holding a deadband: the explanation's catalogue, on TG Type I, may not see it, and the
    plain record states a droop 25 % off). Said, not silently kept. Without the test, any one
    event's TGOV1 would be said to hold a band: one event size always trades a band against
    the droop, whatever the plant."""
    plain = fits[structure.name]
    out = {}
    for effect in structure.effects:
        freed = [fits[v.name] for v in structure.optional_variants()
                 if v.name in fits and structure.freed_effect(v.name) == effect]
        if effect == kept or not freed:
            continue
        best = min(freed, key=lambda f: f.bic)
        if plain.data_term is None or best.data_term is None:
            continue
        p = float(chi2.sf(plain.data_term - best.data_term, max(best.n_estimated - plain.n_estimated, 1)))
        if p >= LEANING:
            continue
        se = plain.identifiability.relative_se_by_name if plain.identifiability else {}
        moves = {n: best.parameters[n] / v - 1 for n, v in plain.parameters.items()
                 if n in structure.estimate and n in best.parameters and v and se.get(n, 0.0) <= WEAK_SE}
        moved = [f"{n.removeprefix('gov.')} from {plain.parameters[n]:.4g} to {best.parameters[n]:.4g} "
                 f"({100 * m:+.0f} %)" for n, m in moves.items() if abs(m) > max(MOVED, 2 * se.get(n, 0.0))]
        if not moved:
            continue
        parts = ", ".join(f"{n.removeprefix('gov.')} = {best.parameters[n]:.3g}" for n in structure.parts(effect)
                          if n in best.parameters)  # the best may free some of them (IEEEG1+rate_limit(Uc))
        out[effect] = (f"the recordings do not determine a {effect.replace('_', ' ')}: freed, it fits "
                       f"{best.bic - plain.bic:+.1f} in BIC ({parts}; likelihood-ratio p {p:.2g}) and moves {' and '.join(moved)}; the record "
                       "states none, so its values hold the choice"
                       + ("; events of two sizes separate a band from the droop" if effect == "deadband" else ""))
    return out


@dataclass(frozen=True)
class _Kept:
    """Which effect's optional parts the kept fit freed (None: the plain fit), the plain
    fit's BIC, and each effect's best freed fit's (None where it was not fitted)."""

    effect: str | None
    plain_bic: float
    best: dict[str, float | None]

    def why_not(self, effect: str) -> str:
        """Why the optional parts of ``effect`` are not in the record."""
        bic = self.best.get(effect)
        if bic is not None and bic <= self.plain_bic - THRESHOLD and self.effect is not None:
            return (f"freeing them beat the plain fit, but {self.effect}'s parts beat it by more, and the two are "
                    "not freed together")
        return f"freeing them did not win by {THRESHOLD:g} in BIC: the recordings do not determine it"


def _carrying(structure: Structure, missing: list[str], open_: list[str], kept: _Kept,
              parameters: dict[str, float], relative_se: dict[str, float], moved: Sequence[str] = ()) -> list[str]:
    """What the kept fit cannot carry, in words: an effect the explanation names that the
    structure has no part for, or holds off in its file, or whose optional parts were not
    kept (why: :meth:`_Kept.why_not`; a droop may then have absorbed a deadband); an effect
    the explanation does not exclude (``open_``) that an optional part would carry; and an
    optional part kept that the recordings still leave undetermined."""
    out = []
    said = [e for e in open_ if e in structure.effects and e != kept.effect]
    for effect in said:
        parts = ", ".join(n.removeprefix("gov.") for n in structure.parts(effect))
        out.append(f"the recordings do not exclude a {effect.replace('_', ' ')} of a material size, which "
                   f"{structure.name}'s {parts} would carry, and do not determine one: the record states none"
                   + ("; its droop may have absorbed a band (events of two sizes separate them)"
                      if effect == "deadband" else ""))
    unfreed = [e for e in missing if e in structure.effects]
    held = [e for e in missing if e not in structure.effects and e in CARRIES.get(structure.name, ((), ""))[0]]
    absent = [e for e in missing if e not in unfreed and e not in held]
    if absent:
        out.append(f"it cannot carry {', '.join(absent)} "
                   f"({CARRIES.get(structure.name, ((), 'no part for them'))[1]})")
    for effect in held:
        parts = ", ".join(f"{n.removeprefix('gov.')} = {v:g}" for n, v in NEUTRAL[structure.name][effect].items())
        out.append(f"the explanation names {effect}, which its structure file holds off ({parts}): free those parts "
                   f"in [optional] (carries = \"{effect}\") for a record that carries it")
    for effect in unfreed:
        parts = ", ".join(n.removeprefix("gov.") for n in structure.parts(effect))
        out.append(f"the explanation names {effect}, which {structure.name}'s {parts} would carry, but "
                   f"{kept.why_not(effect)}, and the record states none"
                   + ("; its droop may have absorbed the band" if effect == "deadband" else ""))
    quiet = [e for e in structure.effects if e not in moved]  # a moved one is said by _moved_by
    if kept.effect is None and not unfreed and not said and quiet and any(b is not None for b in kept.best.values()):
        freed = "; ".join(f"{', '.join(n.removeprefix('gov.') for n in structure.parts(e))} ({e})" for e in quiet)
        out.append(f"freeing {freed} did not win by {THRESHOLD:g} in BIC")
    if kept.effect is not None:
        weak = [(n, relative_se[n]) for n in structure.parts(kept.effect) if relative_se.get(n, 0.0) > WEAK_SE]
        for name, se in weak:
            out.append(f"its {name.removeprefix('gov.')} = {parameters[name]:.3g} is not determined by the "
                       f"recordings (relative standard error {100 * se:.0f} %): an event barely beyond it, or "
                       "none that reaches it")
    return out


def _recommend(records: list[StandardRecord]) -> tuple[str | None, str, str | None, list[str]]:
    """The record the criterion prefers, why, the first by BIC where a simpler one tied
    with it is recommended instead, and every simpler record that ties with the first
    (recommended or passed over): the first by BIC (with its optional parts where they
    won); a simpler one only where it ties with it (within the selection threshold), and
    then both are said. A winner that is not within the noise is still recommended, and
    said to be so."""
    if not records:
        return None, "no standard structure was given", None, []
    ranked = sorted(records, key=lambda r: r.bic)
    first = ranked[0]
    ties = sorted((r for r in ranked[1:] if r.bic - first.bic < THRESHOLD and r.n_estimated < first.n_estimated),
                  key=lambda r: (r.n_estimated, r.bic))
    tying = [r.fit for r in ties]
    # a simpler record that cannot carry what the explanation found (a rate limit) is not
    # as good a record, however close its fit to these tests: on a larger event it is wrong
    short = [r for r in ties if r.cannot_carry and not first.cannot_carry]
    # nor is one held by its bounds, or not within the noise, where the first is neither: its
    # optimum sits on the edge of the search box, so its BIC is a constrained one and its
    # values are the box's, not the tests'. (On make bench-fleet, 4 of 45 identified units'
    # records were ties with estimates on their bounds that failed the tolerance bands; the
    # first had estimates on bounds too in each, so this rule leaves them as they were.)
    held = [r for r in ties if r not in short and ((r.at_bounds and not first.at_bounds)
                                                   or (not r.adequate and first.adequate))]
    ties = [r for r in ties if r not in short and r not in held]
    chosen = ties[0] if ties else first
    if chosen is first:
        runner = ranked[1] if len(ranked) > 1 else None
        clauses = [f"first by BIC ({first.fit}, {first.n_estimated} estimated parameters"
                   + (f"; {runner.bic - first.bic:.1f} ahead of {runner.fit}" if runner else "") + ")"]
        if short:
            clauses.append(f"{', '.join(r.fit for r in short)} ties with it but cannot carry "
                           f"{', '.join(short[0].cannot_carry)}")
    else:
        clauses = [f"it ties with {first.fit}, the first by BIC ({chosen.bic - first.bic:.1f} behind, within "
                   f"{THRESHOLD:g}), with fewer estimated parameters ({chosen.n_estimated} against "
                   f"{first.n_estimated}): either record fits these tests as well; {first.model} is the richer one"]
    for r in held:  # passed over, whichever record was chosen
        why = (f"its {', '.join(n.split(' ')[0] for n in r.at_bounds)} on their bounds" if r.at_bounds
               and not first.at_bounds else "it is not within the noise")
        clauses.append(f"{r.fit} ties with {first.fit} but {why}")
    clauses.append("within the noise on every test" if chosen.adequate else f"NOT within the noise ({chosen.words})")
    return chosen.model, "; ".join(clauses), None if chosen is first else first.fit, tying


def _explanation(d: Diagnosis) -> Explanation:
    n, after = d.named, d.adequacy.after
    return Explanation(n.verdict, n.effect, tuple(n.effects), d.adequate, after.p, d.parameters_after,
                       d.parameter_intervals, {t.test: t for t in after.tests}, d.noise, tuple(n.not_excluded),
                       n.separating_test)
