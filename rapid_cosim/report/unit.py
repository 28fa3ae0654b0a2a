"""What the validation report says about the unit as a whole: the delivered record, its
parameters and where each came from, the noise model and the diagnosis. Gathered here as
plain dataclasses; :mod:`.sections` renders them.

Why gathered apart from the page: each piece can fail on its own (a bench that is no
standard governor has no record, a campaign without quiet data no noise fit), and the page
then says why instead of failing whole.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..calibration.record import DOCUMENTED, ESTIMATED, standard_record
from ..errors import RapidCosimError
from ..estimators.uncertainty import Uncertainty
from ..exchange import NoLayout, layout, pslf_dyd, psse_dyr
from ..experiment import Experiment
from ..noise import campaign_noise
from .archives import ArchivedRun


@dataclass(frozen=True)
class ParameterRow:
    name: str  # as the bench names it, e.g. gov.R
    value: float
    origin: str  # estimated, documented or bench default
    interval: tuple[float, float] | None = None  # estimated only
    searched: tuple[float, float] | None = None  # estimated only
    label: str = ""


@dataclass(frozen=True)
class DeliveredRecord:
    """The standard model's records (None when the run's bench carries none, ``note`` says
    why; ``dyd`` None without the machine's MVA base) and every parameter's row."""

    model: str | None
    dyr: str | None
    dyd: str | None
    note: str
    parameters: tuple[ParameterRow, ...]


@dataclass(frozen=True)
class NoiseRow:
    tests: tuple[str, ...]
    description: str
    family: str
    detail: str  # quiet data behind it, or "stated in the config"


@dataclass(frozen=True)
class NoiseSummary:
    source: str
    rows: tuple[NoiseRow, ...]
    levels: dict[str, float]  # each test's pre-event noise level (pu), as the metrics use it


@dataclass(frozen=True)
class DiagnosisTest:
    test: str
    variance_ratio: float
    rmse_over_noise: float
    p: float
    p_holm: float
    adequate: bool


@dataclass(frozen=True)
class DiagnosisSummary:
    path: Path
    verdict: str
    reason: str
    adequate: bool
    alpha: float
    p: float
    pooled_variance_ratio: float
    tests: tuple[DiagnosisTest, ...]
    noise: tuple[str, ...]  # the diagnosis's recorder noise models, described


def delivered_record(run: ArchivedRun, x, unc: Uncertainty | None, *, bus: int = 1, machine_id: str = "1",
                     mva: float | None = None) -> DeliveredRecord:
    """The run's standard record in both formats, and the parameter table: estimated
    parameters with their intervals, then the documented (fixed) values, then the bench's
    defaults that the record carries."""
    problem = run.inputs.problem
    estimated = []
    for k, (name, label) in enumerate(zip(problem.names, problem.labels)):
        interval = None if unc is None else (float(unc.interval[k, 0]), float(unc.interval[k, 1]))
        estimated.append(ParameterRow(name, float(x[k]), ESTIMATED, interval,
                                      (float(problem.space.lower[k]), float(problem.space.upper[k])), label))
    parameters = dict(zip(problem.names, map(float, x)))
    try:
        rec = standard_record(run.inputs, parameters, x, source=str(run.path))
    except RapidCosimError as e:
        return DeliveredRecord(None, None, None, str(e), tuple(estimated + _documented(run.inputs.experiments)))
    dyr, dropped = psse_dyr.format_record(rec.model.name, rec.values, bus=bus, machine_id=machine_id)
    rows = list(estimated)
    for key in sorted(rec.values, key=lambda k: (rec.origin[k] != DOCUMENTED, k in dropped, k)):
        if rec.origin[key] != ESTIMATED:
            origin = rec.origin[key] + (" (no field in the record)" if key in dropped else "")
            rows.append(ParameterRow(f"gov.{key}", rec.values[key], origin))
    dyd = None
    shown = layout(rec.model.name, rec.values).name
    note = (f"PSS/E .dyr and PSLF .dyd records of {shown}, machine {machine_id} at bus {bus}, as "
            "rapid-cosim export writes them (conversions: rapid_cosim.exchange.tables).")
    if mva is not None:
        try:
            dyd, _ = pslf_dyd.format_record(rec.model.name, rec.values, bus=bus, machine_id=machine_id, mva=mva)
        except NoLayout as e:  # a deadband: the .dyr's D layout carries it
            note += f" No .dyd record: {e}."
    else:
        note += " No .dyd record: it states the machine's MVA base, which the run does not know (give --mva)."
    return DeliveredRecord(shown, dyr, dyd, note, tuple(rows))


def _documented(experiments: Sequence[Experiment]) -> list[ParameterRow]:
    """The governor's values fixed in the configs, one row per value (a value that
    differs between tests gets a row for each, named by test)."""
    values: dict[str, dict[str, float]] = {}
    for e in experiments:
        for name, v in e.fixed.items():
            if name.startswith("gov."):
                values.setdefault(name, {})[e.name] = float(v)
    rows = []
    for name in sorted(values):
        distinct = set(values[name].values())
        if len(distinct) == 1:
            rows.append(ParameterRow(name, distinct.pop(), DOCUMENTED))
        else:
            rows += [ParameterRow(f"{name} ({test})", v, DOCUMENTED) for test, v in values[name].items()]
    return rows


def noise_summary(experiments: Sequence[Experiment]) -> NoiseSummary:
    """The experiments' own ``[noise]`` models when they state them, else one model per
    recorder fitted to the quiet data (:func:`rapid_cosim.noise.campaign_noise`)."""
    levels = {e.name: float(s) for e in experiments if e.noise_sigma for s in list(e.noise_sigma.values())[:1]}
    stated = [e for e in experiments if e.noise_models]
    if stated:
        rows = tuple(NoiseRow((e.name,), m.describe(), m.family, f"[noise.{out}] of {e.config_path.name}")
                     for e in stated for out, m in e.noise_models.items())
        return NoiseSummary("stated in the experiments' [noise] sections", rows, levels)
    try:
        fits = campaign_noise(list(experiments))
    except (ValueError, RapidCosimError) as e:
        return NoiseSummary(f"no noise model: {e}", (), levels)
    rows, seen = [], set()
    for fit in fits.values():
        if id(fit) in seen:
            continue
        seen.add(id(fit))
        se = ", ".join(f"{v * 100:.0f} %" for v in fit.standard_errors())
        rows.append(NoiseRow(tuple(fit.tests), fit.model.describe(), fit.family,
                             f"{fit.n_samples} quiet samples in {fit.n_stretches} stretches; relative standard "
                             f"errors {se}"))
    return NoiseSummary("fitted by REML to the quiet stretches of the tests, one model per recorder "
                        "(rapid_cosim.noise.campaign_noise)", tuple(rows), levels)


def read_diagnosis(path: str | Path) -> DiagnosisSummary:
    """The verdict and the final model's adequacy from a ``diagnosis.json`` (written by
    ``rapid-cosim diagnose``)."""
    path = Path(path)
    if not path.exists():
        raise RapidCosimError(f"{path}: no such diagnosis (rapid-cosim diagnose writes diagnosis.json)")
    try:
        d = json.loads(path.read_text())
        adequacy = d["adequacy"].get("after", d["adequacy"])
        tests = tuple(DiagnosisTest(name, float(t["variance_ratio"]), float(t["rmse_over_noise"]), float(t["p"]),
                                    float(t["p_holm"]), bool(t["adequate"]))
                      for name, t in adequacy["tests"].items())
        noise = tuple(f"{', '.join(r.get('tests', []))}: {r['description']}"
                      for r in d.get("noise", {}).get("recorders", []))
        return DiagnosisSummary(path, str(d["verdict"]), str(d.get("reason", "")), bool(d["adequate"]),
                                float(adequacy["alpha"]), float(adequacy["p"]),
                                float(adequacy["pooled_variance_ratio"]), tests, noise)
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        raise RapidCosimError(f"{path}: not a diagnosis written by rapid-cosim diagnose ({type(e).__name__}: {e})") \
            from None
