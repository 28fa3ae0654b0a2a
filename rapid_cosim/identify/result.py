"""What an identification returns: the explanation, each standard record with its
fidelity, and the recommendation; as JSON and as the Markdown the CLI prints."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

from ..diagnose.adequacy import TestAdequacy
from ..diagnose.catalogue import NONE, VerdictKind
from ..diagnose.result import Advice
from .unit import NO_HOLDOUT

# What each standard structure can represent of the effect catalogue, as its own
# parameters (PES-TR1 2013 and the PSS/E Model Library block diagrams; the deadbands in the
# D layouts of PowerWorld and ORNL GridKit), and in words.
CARRIES: dict[str, tuple[tuple[str, ...], str]] = {
    "TGOV1": (("deadband",), "TGOV1 has valve position limits and, written as TGOV1D, a speed deadband; no rate "
                             "limits, delay or load controller"),
    "IEEEG1": (("rate_limit", "deadband"), "IEEEG1 has valve rate limits (Uo, Uc), position limits and, written "
                                           "as IEEEG1D, a speed deadband; no delay or load controller"),
    "GGOV1": (("rate_limit", "deadband", "output_limit"),
              "GGOV1 has valve rate limits, a speed deadband and a load (temperature) limiter; no delay or "
              "separate load controller"),
    "HYGOV": (("deadband",), "HYGOV has one gate velocity limit, the same both ways, gate position limits and, "
                             "written as HYGOVD, a speed deadband"),
    "GAST": (("output_limit",), "GAST has fuel valve position limits and a temperature (load) limit; no rate "
                                "limits, deadband, delay or load controller"),
}
# A part that is off at its neutral value (a band of 0, a rate of +-1 pu/s that no event
# reaches) carries nothing: a fit carries the effect only where the part is estimated, freed,
# or held at another value.
NEUTRAL: dict[str, dict[str, dict[str, float]]] = {
    "TGOV1": {"deadband": {"gov.db": 0.0}},
    "IEEEG1": {"rate_limit": {"gov.Uo": 1.0, "gov.Uc": -1.0}, "deadband": {"gov.db": 0.0}},
    "GGOV1": {"deadband": {"gov.db": 0.0}},
    "HYGOV": {"deadband": {"gov.db": 0.0}},
}
DELIVERED = {"dyr": "PSS/E record (.dyr)", "dyd": "PSLF record (.dyd)", "report": "validation report",
             "pdf": "validation report (PDF)"}


def recording_story(recordings: dict[str, dict]) -> list[str]:
    """The recordings in a few lines: one for those on regular stamps with nothing
    repaired, masked or bridged, one for those that differ only by jitter, and every fact
    of the others."""
    def only_jitter(r: dict) -> bool:  # stamps off their grid, and nothing else to say
        bases = r["timebase"].values()
        return not (r["masked"] or r["bridged"] or r["rocof_unfit"] or r.get("notes")) and all(
            not (b["dropped"] or b["repeated"] or b["reordered"]) for b in bases) and not all(
            b.get("regular", False) for b in bases)

    plain = [name for name, r in recordings.items() if r["plain"]]
    jittered = [name for name, r in recordings.items() if not r["plain"] and only_jitter(r)]
    lines = [f"recordings: {', '.join(plain)} on regular stamps, nothing repaired, masked or bridged"] if plain else []
    if jittered:
        rms = [1e3 * b["jitter_rms"] for name in jittered for b in recordings[name]["timebase"].values()]
        lines.append(f"recordings: {', '.join(jittered)} with jittered stamps ({min(rms):.2g}-{max(rms):.2g} ms RMS), "
                     "no frame missing, nothing repaired, masked or bridged")
    for name, r in recordings.items():
        if name not in plain and name not in jittered:
            lines += [f"recording {name}: {line}" for line in r["lines"]]
    return lines


def cannot_carry(structure: str, effects: Sequence[str], *, estimated: Sequence[str] = (),
                 fixed: Mapping[str, float] | None = None) -> list[str]:
    """The explanation's effects that ``structure`` as fitted has no part for, or holds
    off: a part (:data:`NEUTRAL`) neither ``estimated`` (freed included) nor ``fixed`` away
    from its neutral value (the bench's default is that value) carries nothing."""
    fixed = dict(fixed or {})

    def off(effect: str) -> bool:
        parts = NEUTRAL.get(structure, {}).get(effect)
        return parts is not None and all(n not in estimated and fixed.get(n, v) == v for n, v in parts.items())

    carried = {e for e in CARRIES.get(structure, ((), ""))[0] if not off(e)}
    return [e for e in effects if e not in carried]


@dataclass(frozen=True)
class TestFidelity:
    """How a standard record fits one test, beside the explanation (TG Type I and the
    effect catalogue) on the same test."""

    rmse_over_noise: float
    variance_ratio: float
    p: float  # the adequacy test's, Holm-adjusted over the tests
    adequate: bool
    explanation_rmse_over_noise: float | None  # None where no explanation was run


@dataclass
class StandardRecord:
    model: str  # TGOV1, IEEEG1, GGOV1, HYGOV
    fit: str  # the fit kept: the model, or the model with its optional parts ("IEEEG1+rate_limit")
    optional_freed: bool
    parameters: dict[str, float]
    n_estimated: int
    bic: float
    adequate: bool
    variance_ratio: float
    tests: dict[str, TestFidelity]
    cannot_carry: list[str]
    words: str
    archive: str
    at_bounds: list[str] = field(default_factory=list)
    relative_se: dict[str, float] = field(default_factory=dict)  # each estimate's, from the Fisher information
    cautions: list[str] = field(default_factory=list)  # the clauses of words after the fit's: what it cannot carry
    freed_effect: str | None = None  # the effect whose optional parts the kept fit freed (None: the plain fit)
    # effects its optional parts would carry that the explanation names or does not exclude,
    # and the kept fit does not carry: the recordings do not determine them (a fleet flags them)
    undetermined: list[str] = field(default_factory=list)

    def fidelity(self, tests: Sequence[str], *, failing: bool = False) -> str:
        """RMSE over the noise per test of ``tests`` it has (``failing``: marked where the
        test finds it inadequate)."""
        return ", ".join(f"{t} {self.tests[t].rmse_over_noise:.2f}"
                         + (" (fails)" if failing and not self.tests[t].adequate else "")
                         for t in tests if t in self.tests)


@dataclass(frozen=True)
class Explanation:
    """The explanation (TG Type I and the effect catalogue) in short: its verdict (the
    sentence, the effect or kind's word, the effects named), whether its final model fits
    to the noise (campaign ``p``, each test's adequacy), that model's parameters with their
    90 % intervals, what no test excluded at a material size and the staged test that would
    separate it. identification.json holds it as :meth:`to_json` writes it."""

    verdict: str = NONE
    effect: str = NONE
    effects: tuple[str, ...] = ()
    adequate: bool = True
    p: float = 1.0
    parameters: dict[str, float] = field(default_factory=dict)
    intervals: dict[str, list[float]] = field(default_factory=dict)
    tests: dict[str, TestAdequacy] = field(default_factory=dict)
    noise: dict = field(default_factory=dict)
    not_excluded: tuple[str, ...] = ()
    separating_test: Advice | None = None

    @property
    def kind(self) -> VerdictKind:
        return VerdictKind.of(self.effect)

    def to_json(self) -> dict:
        return {"verdict": self.verdict, "effect": self.effect, "effects": list(self.effects),
                "adequate": self.adequate, "parameters": self.parameters, "intervals": self.intervals,
                "noise": self.noise, "p": self.p, "tests": {k: t.to_json() for k, t in self.tests.items()},
                "not_excluded": list(self.not_excluded),
                "separating_test": self.separating_test.to_json() if self.separating_test else None}


@dataclass
class Identification:
    unit: str
    mva: float | None
    bus: int
    machine_id: str
    training: list[str]
    heldout: list[str]
    explanation: Explanation
    records: list[StandardRecord]
    recommended: str | None
    reason: str
    structure_verdict: str
    seconds: float
    tied_with: str | None = None  # the first by BIC, where a simpler record tied with it is recommended
    ties: list[str] = field(default_factory=list)  # simpler records tying with the first, recommended or not
    files: dict[str, str] = field(default_factory=dict)  # what was delivered: dyr, dyd, report, pdf
    notes: dict[str, str] = field(default_factory=dict)  # why one of those was not written
    reproduced: dict[str, float] = field(default_factory=dict)  # dyr, dyd: read back, largest miss of the fit (pu)
    diagnosis: str = ""  # the explanation as diagnosis.json, for the report
    heldout_configs: list[str] = field(default_factory=list)  # the held-out tests on the recommended record's bench
    recordings: dict[str, dict] = field(default_factory=dict)  # per test: its stamps, masks, bridges (Recording)
    layout_note: str = ""  # the record's layout where it is not its block's plain one (TGOV1D), and what that means

    def record(self, model: str) -> StandardRecord:
        return next(r for r in self.records if r.model == model)

    @property
    def unexplained(self) -> bool:
        """Whether the explanation leaves something unexplained: nothing it knows explains
        the unit, or what it names leaves a remainder (its final model not within the
        noise: the verdict's "+ unexplained remainder")."""
        return self.explanation.kind is VerdictKind.UNEXPLAINED or not self.explanation.adequate

    def to_json(self) -> dict:
        return json.loads(json.dumps({**asdict(self), "explanation": self.explanation.to_json()}, default=float))

    def markdown(self) -> str:
        e = self.explanation
        lines = [f"# Identification of {self.unit}", "",
                 f"Trained on {', '.join(self.training)}"
                 + (f"; held out: {', '.join(self.heldout)}." if self.heldout else f"; {NO_HOLDOUT}."), "",
                 "## The explanation (TG Type I and the effect catalogue)", "",
                 f"**{e.verdict}** (campaign p-value {e.p:.2g}).", "",
                 "| parameter | value | 90 % interval |", "|---|---:|---|"]
        for name, value in e.parameters.items():
            lo_hi = e.intervals.get(name)
            lines.append(f"| {name} | {value:.4g} | {f'[{lo_hi[0]:.4g}, {lo_hi[1]:.4g}]' if lo_hi else '-'} |")
        lines += ["", "## The standard records", "",
                  "| record | fit | estimated | dBIC | pooled variance ratio | within the noise | in words |",
                  "|---|---|---:|---:|---:|---|---|"]
        best = min((r.bic for r in self.records), default=0.0)
        for r in sorted(self.records, key=lambda r: r.bic):
            lines.append(f"| {r.model} | {r.fit} | {r.n_estimated} | {r.bic - best:.1f} | {r.variance_ratio:.3f} | "
                         f"{'yes' if r.adequate else 'no'} | {r.words} |")
        lines += ["", "Fidelity per test (RMSE over the noise level; the explanation's in the last column):", ""]
        tests = list(e.tests)
        lines.append("| test | " + " | ".join(r.model for r in self.records) + " | explanation |")
        lines.append("|---|" + "---:|" * (len(self.records) + 1))
        for t in tests:
            cells = [f"{r.tests[t].rmse_over_noise:.2f}{'' if r.tests[t].adequate else ' (fails)'}"
                     if t in r.tests else "-" for r in self.records]
            lines.append(f"| {t} | " + " | ".join(cells) + f" | {e.tests[t].rmse_over_noise:.2f} |")
        lines += ["", "## The recommended record", "", f"**{self.recommended or 'none'}**: {self.reason}."]
        if self.recommended:
            r = self.record(self.recommended)
            lines += ["", "| parameter | value |", "|---|---:|"]
            lines += [f"| {k} | {v:.5g} |" for k, v in r.parameters.items()]
        for kind, label in DELIVERED.items():
            if kind in self.files or kind in self.notes:
                lines.append(f"\n{label}: " + (f"`{self.files[kind]}`" if kind in self.files
                                                else f"none ({self.notes[kind]})"))
                if kind == "dyr" and self.layout_note:
                    lines.append(f"written as {self.layout_note}.")
        lines += ["", "## The recordings", ""]
        lines += [f"- {name}: {'; '.join(r['lines'])}" for name, r in self.recordings.items()]
        lines += ["", f"{self.seconds:.0f} s."]
        return "\n".join(lines) + "\n"

    def story(self, also: Sequence[str | Path] = ()) -> str:
        """The few lines the CLI ends with: the explanation's verdict, the recommended
        record with its fidelity per test, what was delivered (and why not, where not),
        then ``also`` (the identification's own files)."""
        e = self.explanation
        lines = [f"explanation (TG Type I and the effect catalogue): {e.verdict}, "
                 f"{'adequate' if e.adequate else 'not adequate'} (campaign p {e.p:.2g})"]
        if e.kind is VerdictKind.NONE and e.not_excluded:
            test = e.separating_test
            lines[0] += (f"; not excluded at a material size: {', '.join(e.not_excluded)}"
                         + (f" ({test.words})" if test else ""))
        if self.recommended:
            r = self.record(self.recommended)
            lines.append(f"recommended record: {r.model}" + (f" ({r.fit})" if r.fit != r.model else "")
                         + f", {self.reason}")
            lines.append(f"  RMSE over the noise, training: {r.fidelity(self.training, failing=True)}")
            if self.heldout:
                lines.append(f"  held out: {r.fidelity(self.heldout, failing=True)}")
            else:
                lines.append(f"  note: {NO_HOLDOUT}")
            if r.adequate:  # otherwise the reason says them already (its "NOT within the noise (...)")
                lines += [f"  note: {c}" for c in r.cautions]
        else:
            lines.append(f"recommended record: none ({self.reason})")
        lines += recording_story(self.recordings)
        lines.append("written:")
        for kind, label in DELIVERED.items():
            if kind in self.files:
                miss = self.reproduced.get(kind)
                check = ("" if miss is None else " (read back, it simulates its fit "
                         + (f"to {miss:.0e} pu" if miss > 0 else "exactly") + " on every test)")
                lines.append(f"  {label + ':':<26} {self.files[kind]}{check}")
                if kind == "dyr" and self.layout_note:
                    lines.append(f"  {'':<26} as {self.layout_note}")
            elif kind in self.notes:
                lines.append(f"  {label + ':':<26} none: {self.notes[kind]}")
        lines += [f"  {'identification:':<26} {path}" for path in also]
        return "\n".join(lines)
