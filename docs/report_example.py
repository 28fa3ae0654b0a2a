"""The validation report's example (make report-example): a synthetic TGOV1 unit with
three staged tests, calibrated on one, and its report with the other two held out, as
HTML, PDF and a screenshot of the page's top (the README's picture).

The unit is R = 0.06, T1 = 0.5 s on a 0.2 Hz under-frequency step; held out: the same
unit on a 0.15 Hz step the other way (it should pass), and a test of another unit
(R = 0.04) that the calibration should not predict (it should fail). Every number on the
page is computed here, from data made here.

    python docs/report_example.py --results results/report-example [--picture docs/validation_report.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapid_cosim.cli import main as rapid_cosim
from rapid_cosim.compiler import ensure_fmu
from rapid_cosim.report.pdf import screenshot
from rapid_cosim.experiment.synthetic import NoiseModel, synthesize, write_experiment

BENCH = "iGrGen.TestBenches.StagedTestTGOV1"
FIXED = {"gov.p_ref": 0.6, "src.t_step": 5.0, "gov.VMAX": 0.95, "gov.T3": 6.0}
ESTIMATE = {"gov.R": {"min": 0.02, "max": 0.12, "label": "R"}, "gov.T1": {"min": 0.1, "max": 2.0, "label": "T1"}}
TESTS = {  # name: (df in Hz, true R, seed, description)
    "step": (-0.2, 0.06, 1, "staged test: frequency 0.2 Hz low at 5 s"),
    "step_up": (0.15, 0.06, 2, "staged test: frequency 0.15 Hz high at 5 s"),
    "other_unit": (-0.2, 0.04, 3, "staged test of another unit (R 0.04): not this model's"),
}


def make_tests(folder: Path, fmu: Path) -> dict[str, Path]:
    configs = {}
    for name, (df, r, seed, description) in TESTS.items():
        fixed = {**FIXED, "src.df": df}
        t, y = synthesize(fmu, {**fixed, "gov.R": r, "gov.T1": 0.5}, duration=40.0,
                          noise=NoiseModel(white_sigma=0.0008), rng=np.random.default_rng(seed))
        configs[name] = write_experiment(folder / name, model=BENCH, time=t, values=y, fixed=fixed,
                                         estimate=ESTIMATE, description=description,
                                         fitness={"offset": True, "noise": "pre-step", "pre_step_end": 5.0})
    return configs


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", default="results/report-example")
    ap.add_argument("--picture", help="also write a PNG of the page's top here")
    ap.add_argument("--package", default="modelica/iGrGen")
    ap.add_argument("--fmus", default="fmus")
    args = ap.parse_args(argv)
    folder = Path(args.results)
    configs = make_tests(folder, ensure_fmu(BENCH, package=args.package, fmu_dir=args.fmus))
    archive = folder / "run.h5"
    archive.unlink(missing_ok=True)
    models = ["--package", args.package, "--fmus", args.fmus]
    steps = [["estimate", str(configs["step"]), "--method", "nm", "--archive", str(archive), "--quiet", *models],
             ["report", str(archive), "--out", str(folder / "unit.html"), "--holdout", str(configs["step_up"]),
              str(configs["other_unit"]), "--mva", "110", "--pdf", *models]]
    for step in steps:
        print("$ rapid-cosim " + " ".join(step), flush=True)
        if rapid_cosim(step) != 0:
            return 1
    if args.picture:
        print(f"wrote {screenshot(folder / 'unit.html', args.picture, width=1100, height=1300)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
