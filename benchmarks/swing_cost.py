"""What the swing term costs a simulation (issue 26's goal: under 5 % more).

The recorded-frequency benches gained the rotor's inertial and damping power
(iGrGen.Machines.SwingPower): an input ``rocof``, an algebraic block and an output ``pe``.
No state is added, so the cost is the extra input column interpolated at each step and
the block's few operations. To measure exactly that, the bench without the swing term
is the same source with those lines removed (``FrequencyInputTGOV1NoSwing``, built
into a temporary copy of the package, never into the repository's): both FMUs come from
one compiler and one package, so their difference is the swing term and nothing else.

Both benches run the same recorded event (``experiments/electrical/tgov1_on``: ANDES,
60 s at 30 frames/s), its parameters varied over R, T1 and T3 as a calibration does:
without the swing term driven by f_dev and compared on ``pm``; with it driven by f_dev
and the derived ROCOF and compared on ``pe``. Each runner (exponential, the default, and
compiled CVODE) one set per call and in batches of 100; the timings take turns so a
shared machine loads both alike. Deriving the ROCOF happens once per experiment, when
its input table is built, and is timed apart.
"""

from __future__ import annotations

import re
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EVENT = ROOT / "experiments" / "electrical" / "tgov1_on"
BENCH = "iGrGen.TestBenches.FrequencyInputTGOV1"
NO_SWING = "iGrGen.TestBenches.FrequencyInputTGOV1NoSwing"


def no_swing_source(text: str) -> str:
    """The TGOV1 recorded-frequency bench without its swing term: no rocof input, no
    SwingPower block, no pe output (the bench as it was before issue 26; its
    documentation dropped, which the compiler does not read)."""
    body = text[:text.index("  annotation(Documentation")]
    kept = [line for line in body.splitlines() if not re.search(r"\bmach\b|\brocof\b|\bpe\b", line.split('"')[0])]
    return "\n".join(kept).replace("model FrequencyInputTGOV1 ", "model FrequencyInputTGOV1NoSwing ") + \
        "\nend FrequencyInputTGOV1NoSwing;\n"


def build_pair(workdir: Path) -> tuple[Path, Path]:
    """Both FMUs from one temporary copy of the package: (without, with the swing term)."""
    from rapid_cosim.compiler import build_models

    package = workdir / "iGrGen"
    shutil.copytree(ROOT / "modelica" / "iGrGen", package)
    benches = package / "TestBenches"
    (benches / "FrequencyInputTGOV1NoSwing.mo").write_text(
        no_swing_source((benches / "FrequencyInputTGOV1.mo").read_text()))
    order = benches / "package.order"
    order.write_text(order.read_text().rstrip("\n") + "\nFrequencyInputTGOV1NoSwing\n")
    built = build_models([NO_SWING, BENCH], package=package, fmu_dir=workdir / "fmus", log=lambda *_: None)
    return built[0].fmu, built[1].fmu


def measure(repeats: int = 15) -> dict:
    """Seconds per simulation, the best of ``repeats``: {(bench, runner, "single"|"batch"):
    s}; the median over the repeats of the ratio with / without, each pair timed back to
    back: {("ratio", runner, mode): ratio}; and the ROCOF's derivation once per
    experiment."""
    from rapid_cosim.experiment import load_experiment
    from rapid_cosim.simulator import Simulator
    from rapid_cosim.simulator.rocof import derive_rocof

    exp = load_experiment(EVENT / "config.toml")
    table = exp.input_table
    f_dev = table.values[:, table.names.index("f_dev")]
    times = exp.windowed_data().time
    fixed = {k: v for k, v in exp.fixed.items() if k.startswith("gov.") or k == "f_nom"}
    rng = np.random.default_rng(0)
    varied = np.column_stack([rng.uniform(0.03, 0.08, 100), rng.uniform(0.2, 1.5, 100), rng.uniform(3, 12, 100)])
    names = [*fixed, "gov.R", "gov.T1", "gov.T3"]
    sets = np.column_stack([np.tile(list(fixed.values()), (len(varied), 1)), varied])
    with tempfile.TemporaryDirectory() as tmp:
        without, with_ = build_pair(Path(tmp))
        plain = Simulator(without)
        swing = Simulator(with_)
        swing_sets = np.column_stack([sets, np.full(len(sets), exp.fixed["mach.H"])])
        calls = {}
        for runner in ("exponential", "compiled"):
            p0 = plain.prepare(names, output_times=times, input_time=table.time, inputs={"f_dev": f_dev},
                               outputs=["pm"], runner=runner)
            p1 = swing.prepare([*names, "mach.H"], output_times=times, input_time=table.time,
                               inputs=table, outputs=["pe"], runner=runner)
            for bench, p, s in (("without", p0, sets), ("with", p1, swing_sets)):
                rows = [s[i:i + 1] for i in range(len(s))]
                calls[bench, runner, "single"] = (lambda p=p, rows=rows: [p.run(r) for r in rows]), len(rows)
                calls[bench, runner, "batch"] = (lambda p=p, s=s: p.run(s)), len(s)
        best = dict.fromkeys(calls, np.inf)
        ratios = {key[1:]: [] for key in calls if key[0] == "with"}
        for fn, _ in calls.values():
            fn()  # warm up
        for _ in range(repeats):
            seconds = {}
            for key, (fn, count) in calls.items():
                t0 = time.perf_counter()
                fn()
                seconds[key] = (time.perf_counter() - t0) / count
                best[key] = min(best[key], seconds[key])
            for pair in ratios:  # the two benches measured back to back: a shared machine's load cancels
                ratios[pair].append(seconds[("with", *pair)] / seconds[("without", *pair)])
    derive = min(_timed(lambda: derive_rocof(table.time, f_dev, breaks=(exp.pre_step_end,))) for _ in range(20))
    return {**best, **{("ratio", *pair): float(np.median(r)) for pair, r in ratios.items()},
            "derive": derive, "samples": times.size}


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def bench_swing() -> None:
    figures = measure()
    print(f"swing: the swing term's cost per simulation, recorded event {EVENT.name} ({figures['samples']} samples, "
          "60 s at 30 frames/s); bench without it (f_dev in, pm out) and with it (f_dev and rocof in, pe out), "
          "100 sets of R, T1, T3, one core")
    for runner in ("exponential", "compiled"):
        for mode, label in (("single", "one set per call"), ("batch", "batches of 100")):
            a, b = figures["without", runner, mode], figures["with", runner, mode]
            print(f"  {runner:11s} {label:17s} without {1e3 * a:7.3f} ms   with {1e3 * b:7.3f} ms   "
                  f"ratio of the best {b / a:5.3f}, median of paired {figures['ratio', runner, mode]:5.3f}"
                  "   (goal < 1.05)")
    print(f"  deriving the ROCOF (Savitzky-Golay, 0.3 s, split at the event): {1e3 * figures['derive']:.3f} ms once "
          "per experiment, not per simulation")
