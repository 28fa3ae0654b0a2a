"""Synthetic studies of the workflow: campaigns with a known effect hidden in the data.

Each case (:mod:`.campaigns`: an invented plant, an effect of realistic size or none, a
recorder with white plus slow noise, jitter and quantisation) is simulated as a campaign
of staged tests or of recorded events, and :func:`diagnose` runs on it. A confusion
matrix of the true effect against the verdict measures the workflow.

The campaign's shape decides what can be told apart: with three 80 s tests at 5 Hz (an
earlier version of this study) a documented T4 off by x2 was named in 1 of 5 campaigns
(mostly ``ambiguous`` with T5) and a delay and a measurement lag were confused in 2 of
10; with the field's record length and rate, 4 of 5 and 1 of 10.
"""

from __future__ import annotations

import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..compiler.source import ModelSource
from ..experiment import load_experiment
from .campaigns import CAMPAIGN, FOREIGN, SINGLE_SIZE, Case, draw_case, write_campaign  # noqa: F401  (re-exported)
from .catalogue import AMBIGUOUS, CATALOGUE, EFFECTS, NONE, UNEXPLAINED, VARIANTS, VerdictKind
from .workflow import DiagnoseOptions, Diagnosis, diagnose

# The physical effects a plant can hide (the freed documented constants are studied apart).
HIDDEN = tuple(e for e, v in CATALOGUE.items() if not v.relative)


@dataclass
class CaseResult:
    case: Case
    diagnosis: Diagnosis
    seconds: float
    named_first: str = field(init=False)
    gap_shrink: float | None = field(init=False)

    def __post_init__(self):
        d = self.diagnosis.named
        self.named_first = d.effects[0] if d.effects else d.effect
        # no model was added for these verdicts, so there is no shrink to measure
        self.gap_shrink = None if d.kind is not VerdictKind.NAMED else _shrink(self.diagnosis,
                                                                                           self.case.noise.sigma)

    @property
    def outcome(self) -> str:
        """The verdict as the confusion matrix counts it: a named effect, ``none``,
        ``ambiguous``, ``unexplained``, or ``+remainder`` (named, model still inadequate)."""
        d = self.diagnosis
        if d.kind is not VerdictKind.NAMED:
            return d.effect
        return self.named_first if d.adequate else "+remainder"

    @property
    def correct(self) -> bool:
        """The hidden effect named first (the model adequate); with several hidden, all of
        them named; with a foreign one, ``unexplained``; with a variant of an effect, the
        variant or its parent named, or the variant among the stories the verdict cannot
        tell apart."""
        d = self.diagnosis.named
        if self.case.foreign:
            return d.kind is VerdictKind.UNEXPLAINED
        if len(self.case.effects) > 1:
            return set(d.effects) == set(self.case.effects)
        if self.case.truth in VARIANTS:
            return self.named_first in (self.case.truth, VARIANTS[self.case.truth].variant_of) or (
                d.kind is VerdictKind.AMBIGUOUS and self.case.truth in d.candidates)
        return self.named_first == self.case.truth

    @property
    def documentation_blamed(self) -> bool:
        """A documented constant named off its value while the plant's documentation is
        right, and the verdict does not also name the variant it cannot rule out."""
        if any(e.startswith("doc_") for e in self.case.effects):
            return False
        d = self.diagnosis.named
        named = set(d.effects) | {c for label in d.candidates for c in label.split("+")}
        blamed = any(e.startswith("doc_") for e in named)
        return blamed and not (named & set(VARIANTS))

    @property
    def wrong_whole_story(self) -> bool:
        """A catalogue name given as the whole story (adequate model) that is wrong."""
        d = self.diagnosis
        return d.kind is VerdictKind.NAMED and d.adequate and not self.correct


def _shrink(d: Diagnosis, sigma: float) -> float | None:
    """1 - gap after / gap before, the gap being the RMS residual above the *true* noise
    level of the synthetic data (known here; the workflow had to estimate it)."""
    def gap(which: dict) -> float:
        rmse2 = np.mean([v["rmse"] ** 2 for v in which.values()])
        return float(np.sqrt(max(rmse2 - sigma ** 2, 0.0)))

    before = gap(d.gap_before)
    return None if before == 0 else 1.0 - gap(d.gap_after) / before


def run_case(case: Case, workdir: Path, *, options: DiagnoseOptions, source: ModelSource, held_out: int = 1,
             log: Callable[[str], None] = lambda *_: None) -> CaseResult:
    """Write the case's campaign and diagnose it, the last ``held_out`` tests held out."""
    folder = workdir / case.label
    if folder.exists():
        shutil.rmtree(folder)
    paths = write_campaign(case, folder / "data", source=source)
    experiments = [load_experiment(p) for p in paths]
    split = len(experiments) - held_out
    t0 = time.perf_counter()
    diagnosis = diagnose(experiments[:split], experiments[split:], workdir=folder / "diagnosis", options=options,
                         source=source, log=log)
    return CaseResult(case, diagnosis, time.perf_counter() - t0)


def confusion(results: Sequence[CaseResult]) -> tuple[list[str], list[str], np.ndarray]:
    order = [*EFFECTS, NONE, *FOREIGN]
    truths = [t for t in order if any(r.case.truth == t for r in results)]
    truths += sorted({r.case.truth for r in results} - set(truths))  # pairs
    verdicts = [*EFFECTS, NONE, AMBIGUOUS, UNEXPLAINED, "+remainder"]
    m = np.zeros((len(truths), len(verdicts)), dtype=int)
    for r in results:
        m[truths.index(r.case.truth), verdicts.index(r.outcome)] += 1
    return truths, verdicts, m


def confusion_text(results: Sequence[CaseResult]) -> str:
    truths, verdicts, m = confusion(results)
    short = {v: v[:9] for v in verdicts}
    head = f"{'true / named':16s}" + "".join(f"{short[v]:>10s}" for v in verdicts) + f"{'correct':>9s}"
    lines = [head]
    for i, t in enumerate(truths):
        right = [r for r in results if r.case.truth == t]
        lines.append(f"{t[:16]:16s}" + "".join(f"{n:10d}" for n in m[i]) +
                     f"{sum(r.correct for r in right) / len(right):9.0%}")
    n_ok = sum(r.correct for r in results)
    lines.append(f"overall: {n_ok}/{len(results)} correct ({n_ok / len(results):.0%})")
    shrinks = [r.gap_shrink for r in results if r.gap_shrink is not None and r.correct]
    if shrinks:
        lines.append(f"gap shrink when the effect is added: median {np.median(shrinks):.0%}, "
                     f"min {min(shrinks):.0%} (over {len(shrinks)} correctly named cases)")
    return "\n".join(lines)
