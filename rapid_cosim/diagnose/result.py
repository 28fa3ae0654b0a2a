"""The diagnosis as it is kept and read: the verdict with its evidence (JSON) and the
residual arrays its report plots (HDF5)."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import h5py
import numpy as np

from .adequacy import Adequacy
from .catalogue import VerdictKind
from .selection import Ranked


@dataclass(frozen=True)
class NextBasin:
    """A multistart's runner-up basin: how much worse, and where."""

    delta_bic: float
    parameters: dict[str, float]


@dataclass(frozen=True)
class CandidateSearch:
    """One candidate's multistart: its starts, how many reached the best, each start's end
    above the best (in BIC), and, for an uncertain one, its next basin."""

    starts: int
    reached: int
    waterfall_dbic: list[float]
    next_basin: NextBasin | None = None

    def to_json(self) -> dict:
        row = {"starts": self.starts, "reached": self.reached, "waterfall_dbic": self.waterfall_dbic}
        return row | ({"next_basin": asdict(self.next_basin)} if self.next_basin else {})


@dataclass(frozen=True)
class SearchCertainty:
    """How sure each candidate's optimum is (:mod:`.starts`): the winner and close rivals
    reached by fewer than ``min_reached`` starts are ``uncertain``, said in ``warning``."""

    candidates: dict[str, CandidateSearch]
    uncertain: list[str]
    warning: str
    min_reached: int
    margin_bic: float

    def to_json(self) -> dict:
        return {"candidates": {k: c.to_json() for k, c in self.candidates.items()}, "uncertain": self.uncertain,
                "warning": self.warning, "min_reached": self.min_reached, "margin_bic": self.margin_bic}


@dataclass(frozen=True)
class AdvisedTest:
    """The staged steps an advice proposes: each held ``hold_s`` and returned."""

    steps_hz: tuple[float, ...]
    hold_s: float
    t_step_s: float
    p_ref: float
    redispatch: bool  # at another dispatch than the data's

    @property
    def magnitude_hz(self) -> float:
        return abs(self.steps_hz[0])

    @property
    def signs(self) -> tuple[int, ...]:
        return tuple(1 if s > 0 else -1 for s in self.steps_hz)

    @property
    def seconds(self) -> float:
        return len(self.steps_hz) * (self.t_step_s + 2 * self.hold_s)

    @property
    def size(self) -> tuple:
        """What makes one test larger than another: its step, then its time, then a re-dispatch."""
        return self.magnitude_hz, self.seconds, self.redispatch

    def describe(self) -> str:
        steps = [f"{1000 * s:+.0f} mHz" for s in self.steps_hz]
        if len(set(steps)) == 1:
            times = {1: "", 2: ", twice", 3: ", three times"}.get(len(steps), f", {len(steps)} times")
            what = f"a staged test with df = {steps[0]}{times}"
        else:
            what = "staged tests with df = " + ", then ".join(steps)
        at = f" at a dispatch of {self.p_ref:.2f} pu" if self.redispatch else ""
        return f"{what}{at}, {'each ' if len(steps) > 1 else ''}held {self.hold_s:.0f} s and returned"

    def to_json(self) -> dict:
        return {"df_hz": self.steps_hz[0], "steps_hz": list(self.steps_hz), "hold_s": self.hold_s,
                "t_step_s": self.t_step_s, "t_return_s": self.t_step_s + self.hold_s, "p_ref": self.p_ref,
                "redispatch": self.redispatch}


@dataclass(frozen=True)
class Advice:
    """The next test of an ambiguous verdict (:mod:`.advice`): the rivals, grouped where no
    test of the menu tells them apart; the test proposed (None: nothing to test); the
    chance it settles the choice, the smallest over the rivals and for each (``found``: it
    reaches ``target``); and the words the story says."""

    between: tuple[str, ...]
    groups: tuple[tuple[str, ...], ...]
    test: AdvisedTest | None
    probability: float
    probability_if: dict[str, float]
    median_lead: dict[str, float]
    expected_bic: float  # what the test adds to the first two groups' BIC difference, fits held
    rms_over_noise: float
    found: bool
    target: float
    draws: int
    menu: tuple[tuple[str, float], ...]  # each test screened, with its probability
    words: str

    def to_json(self) -> dict:
        return {"between": list(self.between), "groups": [list(g) for g in self.groups],
                "test": self.test.to_json() if self.test else None, "probability": self.probability,
                "probability_if": self.probability_if, "median_lead": self.median_lead,
                "expected_bic": self.expected_bic, "rms_over_noise": self.rms_over_noise, "found": self.found,
                "target": self.target, "draws": self.draws,
                "menu": [{"test": t, "probability": p} for t, p in self.menu], "advice": self.words}


@dataclass(frozen=True)
class DiagnosisVerdict:
    """What was named: ``effect`` is a catalogue name, ``none``, ``ambiguous`` or
    ``unexplained``; ``effects`` the effects named; ``candidates`` those the data could not
    tell apart; ``reason`` the verdict's notes said once; ``verdict`` the sentence, e.g.
    ``"rate_limit + unexplained remainder"``; what no test excluded, and the staged test
    that would separate the candidates."""

    effect: str
    effects: list[str]
    candidates: list[str]
    reason: str
    verdict: str
    not_excluded: list[str]
    separating_test: Advice | None
    held_out: dict | None

    @property
    def kind(self) -> VerdictKind:
        return VerdictKind.of(self.effect)


@dataclass(frozen=True)
class AdequacyJudgement:
    """Whether the model fits to the noise (:mod:`.adequacy`: per test, with p-values
    against the computed null), before (the base model) and after (the final one); each
    candidate the options asked to judge; what remains unexplained and whether the named
    effects matter (:mod:`.materiality`)."""

    before: Adequacy
    after: Adequacy
    judged: dict[str, Adequacy]
    unexplained: dict | None
    materiality: dict

    @property
    def adequate(self) -> bool:
        return self.after.adequate


@dataclass(frozen=True)
class SearchReport:
    """How the candidates were searched: the ranking by the criterion, the second
    effect's, each candidate's multistart waterfall and which were uncertain
    (``search``), the named effects' profile likelihoods, and the effect's variants
    tried when a documented constant joined it (:mod:`.variants`)."""

    ranking: list[Ranked]
    second_effect_ranking: list[Ranked]
    search: SearchCertainty
    profiles: dict
    variants: dict


@dataclass
class Diagnosis:
    """The verdict with its evidence: what was named (:class:`DiagnosisVerdict`), the
    adequacy (:class:`AdequacyJudgement`), the search (:class:`SearchReport`), and the
    rest as the JSON report holds it: ``noise``, each recorder's noise model with its
    uncertainty and the quiet data's autocorrelation; ``timing``, the time stamps' jitter
    and the variance it could add. :meth:`to_json` writes the one flat report."""

    named: DiagnosisVerdict
    adequacy: AdequacyJudgement
    searched: SearchReport
    features: dict
    gap_before: dict[str, dict]
    gap_after: dict[str, dict]
    parameters_before: dict[str, float]
    parameters_after: dict[str, float]
    parameter_intervals: dict[str, list[float]]
    noise: dict
    timing: dict
    model_written: str | None
    model_file: str | None
    archives: dict[str, str]
    training: list[str]
    heldout: list[str]
    created: str
    residuals: dict[str, dict[str, np.ndarray]] = field(default_factory=dict, repr=False)
    exchanged_intervals: dict[str, list[float]] = field(default_factory=dict)  # at the swapped optimum

    @property
    def effect(self) -> str:
        return self.named.effect

    @property
    def kind(self) -> VerdictKind:
        return self.named.kind

    @property
    def adequate(self) -> bool:
        return self.adequacy.adequate

    def to_json(self) -> dict:
        """The report as diagnosis.json holds it: one flat table, its keys in the order
        its readers and earlier files have them."""
        n, a, s = self.named, self.adequacy, self.searched
        data = {"effect": n.effect, "effects": n.effects, "candidates": n.candidates, "reason": n.reason,
                "verdict": n.verdict, "adequate": a.adequate,
                "adequacy": {"before": a.before.to_json(), "after": a.after.to_json()},
                "unexplained": a.unexplained, "materiality": a.materiality,
                "ranking": [asdict(r) for r in s.ranking],
                "second_effect_ranking": [asdict(r) for r in s.second_effect_ranking],
                "not_excluded": n.not_excluded,
                "separating_test": n.separating_test.to_json() if n.separating_test else None, "held_out": n.held_out,
                "features": self.features, "gap_before": self.gap_before, "gap_after": self.gap_after,
                "parameters_before": self.parameters_before, "parameters_after": self.parameters_after,
                "parameter_intervals": self.parameter_intervals, "noise": self.noise, "search": s.search.to_json(),
                "profiles": s.profiles, "timing": self.timing, "variants": s.variants,
                "candidate_adequacy": {label: {"adequate": j.adequate, "p": j.p,
                                               "pooled_variance_ratio": j.pooled_variance_ratio}
                                       for label, j in a.judged.items()},
                "model_written": self.model_written, "model_file": self.model_file, "archives": self.archives,
                "training": self.training, "heldout": self.heldout, "created": self.created,
                "exchanged_intervals": self.exchanged_intervals}
        return json.loads(json.dumps(data, default=_jsonable))

    def save(self, folder: str | Path) -> tuple[Path, Path]:
        """``diagnosis.json`` (the verdict and evidence) and ``diagnosis.h5`` (the residual
        arrays before and after, which the report plots)."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        js = folder / "diagnosis.json"
        js.write_text(json.dumps(self.to_json(), indent=2) + "\n")
        h5 = folder / "diagnosis.h5"
        with h5py.File(h5, "w") as f:
            f.attrs["effect"] = str(self.named.effect)  # a plain string: h5py takes no str subclass
            f.attrs["json"] = json.dumps(self.to_json())
            for test, arrays in self.residuals.items():
                g = f.create_group(test)
                for key, values in arrays.items():
                    g.create_dataset(key, data=np.asarray(values, dtype=float))
        return js, h5


def _jsonable(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)
