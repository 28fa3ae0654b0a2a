"""The diagnosis as it is kept and read: the verdict with its evidence (JSON) and the
residual arrays its report plots (HDF5)."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import h5py
import numpy as np


@dataclass
class Diagnosis:
    """The verdict with its evidence, as the JSON report holds it.

    ``effect`` is a catalogue name, ``none``, ``ambiguous`` or ``unexplained``;
    ``effects`` lists the effects named; ``adequate`` says whether the final model fits
    to the noise (:mod:`.adequacy`: per test, with p-values against the computed null,
    under ``adequacy``); ``verdict`` is the sentence, e.g. ``"rate_limit + unexplained
    remainder"``. ``noise``: each recorder's noise model with its uncertainty and the
    quiet data's autocorrelation; ``search``: each candidate's multistart waterfall and
    which were uncertain; ``profiles``: the named effects' profile likelihoods;
    ``timing``: the time stamps' jitter and the variance it could add; ``variants``: the
    effect's variants tried when a documented constant joined it (:mod:`.variants`);
    ``candidate_adequacy``: the adequacy of the base, the final model and any candidate
    the options asked to judge."""

    effect: str
    effects: list[str]
    candidates: list[str]
    reason: str
    verdict: str
    adequate: bool
    adequacy: dict
    unexplained: dict | None
    materiality: dict
    ranking: list[dict]
    second_effect_ranking: list[dict]
    not_excluded: list[str]
    separating_test: dict | None
    held_out: dict | None
    features: dict
    gap_before: dict[str, dict]
    gap_after: dict[str, dict]
    parameters_before: dict[str, float]
    parameters_after: dict[str, float]
    parameter_intervals: dict[str, list[float]]
    noise: dict
    search: dict
    profiles: dict
    timing: dict
    variants: dict
    candidate_adequacy: dict
    model_written: str | None
    model_file: str | None
    archives: dict[str, str]
    training: list[str]
    heldout: list[str]
    created: str
    residuals: dict[str, dict[str, np.ndarray]] = field(default_factory=dict, repr=False)
    exchanged_intervals: dict[str, list[float]] = field(default_factory=dict)  # at the swapped optimum

    def to_json(self) -> dict:
        data = asdict(self)
        data.pop("residuals")
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
            f.attrs["effect"] = str(self.effect)  # a plain string: h5py takes no str subclass
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
