"""Synthetic study of structure selection (``make bench-structures``).

The plants are invented here: for each structure of iGrGen.Governors (and TG Type I) a
unit with parameters drawn at random around the models' documented defaults. GGOV1's
load limiter is set 0.03 to 0.06 pu above the higher dispatch (0.8 pu), so that every
power-raising step from there ends on the temperature limit, as a gas turbine near its
rating does, while the steps from 0.6 pu never reach it. Each campaign is the field
campaign's ten staged tests (:data:`STEPS`: the dispatch, step, return, length and
recorder rate of ``../shared/staged_tests``) with the field's noise level (white +
AR(1), about 1.4e-3 pu with a lag-1 correlation near 0.3, and a meter offset); tests 4
and 8 are held out, as ``make structures`` holds them out. Every structure is calibrated
on the campaign with the same estimated parameters whichever generated it
(:data:`ESTIMATE`), the rest at the models' defaults, and the verdict is compared with
the generating structure. When the verdict is ambiguous, the plant is put through the
separating staged test the verdict proposes (the best of the menu, even when the tool
predicts it will not be enough), as an engineer would, and the structures are ranked
again with it among the training tests ("after").
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..calibration import RunOptions
from ..compiler import ensure_fmu
from ..experiment import load_experiment
from ..synthetic import NoiseModel, synthesize, write_experiment
from .structures import Structure, StructureVerdict, select_structure

# The field campaign's ten tests (../shared/staged_tests): (dispatch in pu, step in Hz,
# return time in s or None for a step held to the end, length in s, recorder rate in Hz),
# the step at T_STEP; tests 4 and 8 held out, as make diagnose and make structures do.
STEPS = ((0.6, -0.2, None, 90.0, 10.0), (0.6, -0.2, 60.0, 110.0, 10.0), (0.6, 0.2, None, 90.0, 10.0),
         (0.6, 0.2, 60.0, 110.0, 10.0), (0.8, -0.2, None, 90.0, 25.0), (0.8, -0.2, 60.0, 110.0, 25.0),
         (0.8, 0.2, None, 90.0, 25.0), (0.8, 0.2, 60.0, 110.0, 25.0), (0.6, -0.1, 60.0, 110.0, 10.0),
         (0.6, 0.1, 60.0, 110.0, 10.0))
HELD_OUT = (3, 7)  # tests 4 and 8
T_STEP = 10.0
NOISE = NoiseModel(white_sigma=1e-3, ar1_sigma=1e-3, phi=0.6, offset=0.001)
P_HIGH = 0.8  # the higher dispatch, where a gas turbine nears its temperature limit

# What each structure estimates (bounds), the same for every campaign.
ESTIMATE: dict[str, dict[str, dict]] = {
    "TGTypeI": {"gov.R": {"min": 0.02, "max": 0.12}, "gov.Ts": {"min": 0.1, "max": 20.0, "scale": "log"}},
    "TGOV1": {"gov.R": {"min": 0.02, "max": 0.12}, "gov.T1": {"min": 0.05, "max": 20.0, "scale": "log"},
              "gov.T2": {"min": 0.0, "max": 10.0}, "gov.T3": {"min": 0.5, "max": 30.0, "scale": "log"}},
    "IEEEG1": {"gov.K": {"min": 8.0, "max": 50.0}, "gov.T3": {"min": 0.02, "max": 10.0, "scale": "log"},
               "gov.T5": {"min": 1.0, "max": 30.0, "scale": "log"}, "gov.K1": {"min": 0.05, "max": 0.6}},
    "GGOV1": {"gov.R": {"min": 0.02, "max": 0.12}, "gov.Kpgov": {"min": 1.0, "max": 40.0, "scale": "log"},
              "gov.Kigov": {"min": 0.1, "max": 20.0, "scale": "log"},
              "gov.Ldref": {"min": P_HIGH + 0.01, "max": 1.2}},
    "HYGOV": {"gov.R": {"min": 0.02, "max": 0.12}, "gov.r": {"min": 0.05, "max": 1.0, "scale": "log"},
              "gov.Tr": {"min": 0.5, "max": 20.0, "scale": "log"}, "gov.TW": {"min": 0.1, "max": 4.0, "scale": "log"}},
}
BENCH = {"TGTypeI": "iGrGen.TestBenches.StagedTest", **{g: f"iGrGen.TestBenches.StagedTest{g}"
                                                        for g in ("TGOV1", "IEEEG1", "GGOV1", "HYGOV")}}
# The plants: random units around the defaults (their estimated parameters drawn here).
PLANTS: dict[str, Callable[[np.random.Generator], dict[str, float]]] = {
    "TGTypeI": lambda g: {"gov.R": g.uniform(0.04, 0.07), "gov.Ts": g.uniform(0.5, 5.0)},
    "TGOV1": lambda g: {"gov.R": g.uniform(0.04, 0.07), "gov.T1": g.uniform(0.2, 2.0), "gov.T2": g.uniform(0.5, 3.0),
                        "gov.T3": g.uniform(4.0, 10.0)},
    "IEEEG1": lambda g: {"gov.K": g.uniform(15.0, 30.0), "gov.T3": g.uniform(0.1, 1.0), "gov.T5": g.uniform(4.0, 10.0),
                         "gov.K1": g.uniform(0.2, 0.4)},
    "GGOV1": lambda g: {"gov.R": g.uniform(0.04, 0.07), "gov.Kpgov": g.uniform(5.0, 20.0),
                        "gov.Kigov": g.uniform(1.0, 5.0), "gov.Ldref": P_HIGH + g.uniform(0.03, 0.06)},
    "HYGOV": lambda g: {"gov.R": g.uniform(0.04, 0.07), "gov.r": g.uniform(0.2, 0.6), "gov.Tr": g.uniform(2.0, 8.0),
                        "gov.TW": g.uniform(0.5, 2.0)},
}


@dataclass
class StructureCase:
    truth: str
    seed: int
    plant: dict[str, float]
    verdict: StructureVerdict | None = None
    followup: StructureVerdict | None = None  # after the separating test an ambiguous verdict proposed
    seconds: float = 0.0

    @property
    def named(self) -> str:
        return self.verdict.structure if self.verdict else "?"

    @property
    def named_after(self) -> str:
        """The verdict once the proposed separating test (if any) is run too."""
        return (self.followup or self.verdict).structure if self.verdict else "?"

    @property
    def first(self) -> str:
        return self.verdict.ranking[0].name if self.verdict else "?"


def structure_files(folder: Path) -> list[Path]:
    """One structure file per model, estimating :data:`ESTIMATE`."""
    from ..experiment import render_config

    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, estimate in ESTIMATE.items():
        path = folder / f"{name}.toml"
        path.write_text(render_config({"structure": {"name": name, "bench": BENCH[name]}, "fixed": {},
                                       "estimate": estimate}))
        paths.append(path)
    return paths


def run_structure_case(truth: str, seed: int, work: Path, *, package, fmu_dir,
                       method: str = "pf:10+nm") -> StructureCase:
    rng = np.random.default_rng([seed, 104729, sorted(PLANTS).index(truth)])
    case = StructureCase(truth, seed, PLANTS[truth](rng))
    folder = work / f"{truth}-{seed}"
    fmu = ensure_fmu(BENCH[truth], package=package, fmu_dir=fmu_dir)
    tests = [_staged_test(fmu, case.plant, p_ref, df, t_return, duration, rate, folder / f"test{k + 1}", rng)
             for k, (p_ref, df, t_return, duration, rate) in enumerate(STEPS)]
    training = [t for k, t in enumerate(tests) if k not in HELD_OUT]
    heldout = [tests[k] for k in HELD_OUT]
    structures = [Structure.load(p) for p in structure_files(folder / "structures")]
    options = RunOptions(method=method, seed=seed)
    start = time.perf_counter()
    case.verdict = select_structure(structures, training, heldout, workdir=folder / "runs", options=options,
                                    package=package, fmu_dir=fmu_dir, log=lambda *_: None)
    proposed = case.verdict.separating_test
    if proposed is not None:  # the engineer runs the test the tool proposes, and asks again
        step = proposed["test"]
        rate = STEPS[0][4]  # recorded like the first training test, which the test was designed from
        extra = _staged_test(fmu, case.plant, step["p_ref"], step["df_hz"], step["t_return_s"],
                             2 * step["t_return_s"] - step["t_step_s"], rate, folder / "proposed", rng)
        case.followup = select_structure(structures, [*training, extra], heldout, workdir=folder / "runs2",
                                         options=options, package=package, fmu_dir=fmu_dir, log=lambda *_: None)
    case.seconds = time.perf_counter() - start
    return case


def _staged_test(fmu, plant: dict, p_ref: float, df: float, t_return: float | None, duration: float, rate: float,
                 folder: Path, rng):
    """One synthetic staged test of ``plant`` (step at T_STEP), as a config on TG Type I."""
    fixed = {"gov.p_ref": p_ref, "src.df": df, "src.t_step": T_STEP,
             **({"src.t_return": t_return} if t_return is not None else {})}
    t, y = synthesize(fmu, {**plant, **fixed}, duration=duration, rate=rate, noise=NOISE, rng=rng)
    return load_experiment(write_experiment(folder, model=BENCH["TGTypeI"], time=t, values=y, fixed=fixed,
                                            estimate={"gov.R": {"min": 0.02, "max": 0.12}},
                                            fitness={"offset": True, "noise": "pre-step", "pre_step_end": T_STEP}))


def confusion_text(cases: list[StructureCase]) -> str:
    names = list(ESTIMATE)
    cols = [*names, "ambiguous", "unexplained"]
    lines = ["true / named " + "".join(f"{c[:11]:>12}" for c in cols) + "     named   first   after"]
    for truth in names:
        mine = [c for c in cases if c.truth == truth]
        if not mine:
            continue
        row = [sum(c.named == col for c in mine) for col in cols]
        named = sum(c.named == truth for c in mine) / len(mine)
        first = sum(c.first == truth for c in mine) / len(mine)
        after = sum(c.named_after == truth for c in mine) / len(mine)
        lines.append(f"{truth:<13}" + "".join(f"{n:>12}" for n in row) + f"  {named:7.0%} {first:7.0%} {after:7.0%}")
    total = len(cases)
    lines.append(f"named the generating structure: {sum(c.named == c.truth for c in cases)}/{total}; "
                 f"ranked it first: {sum(c.first == c.truth for c in cases)}/{total}; named once the separating "
                 f"test proposed for an ambiguous verdict is run too (after): "
                 f"{sum(c.named_after == c.truth for c in cases)}/{total}")
    return "\n".join(lines)
