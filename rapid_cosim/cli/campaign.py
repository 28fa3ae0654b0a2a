"""The staged-test campaign as the make targets run it: each test calibrated with the
paper's two chains and drawn, Table 1, the figures of the paper, the joint fit and its
report, the bench step responses, and the demo. Each function runs estimations (through
:mod:`rapid_cosim.calibration.staged`) and writes reports (through :mod:`rapid_cosim.report`), and
returns what it made for the command line to print.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..compiler.source import ModelSource
from ..fitting.engine import EngineSpec
from ..errors import RapidCosimError
from ..report import table1
from ..report.archives import caption
from ..report.figures import plot_step_responses
from ..report.fits import load_fits, plot_fit_grid, plot_test_fit
from ..report.search import plot_convergence, plot_particle_clouds
from ..simulator import Simulator, Trajectory
from ..calibration.staged import METHODS, archive_path, archived_tests, run_staged_test

# Figs. 3-8 of the paper show tests 1 to 6.
PAPER_FIGURE_TESTS = tuple(f"test{k}" for k in range(1, 7))
# The staged test every bench is shown on: MCR 60 %, df = -200 mHz at 10 s, back at 60 s,
# R = 0.05 (the default) and Ts = 3 s.
STEP_RESPONSE = {"gov.Ts": 3.0, "src.t_return": 60.0}
STEP_RESPONSE_STOP = 110.0


@dataclass(frozen=True)
class StagedTestOutcome:
    test: str
    table: str  # this test's rows of Table 1, as text
    actions: str  # what was done with each chain's archive
    archives: tuple[Path, ...]
    figure: Path
    seconds: float


def staged_tests(configs: Sequence[str | Path], *, results: str | Path, seed: int, engine: EngineSpec,
                 progress: bool, source: ModelSource) -> list[StagedTestOutcome]:
    """Both chains on each staged test (archives reused or resumed, make-like), each
    test's fit figure written."""
    out = []
    for config in configs:
        t0 = time.perf_counter()
        runs = run_staged_test(config, results=results, seed=seed, engine=engine, progress=progress, source=source)
        test = runs[0].test
        rows = [table1.read_row(r.test, r.method.label, r.archive) for r in runs]
        fig = plot_test_fit({r.method.label: r.archive for r in runs}, Path(results) / test / f"{test}.png")
        out.append(StagedTestOutcome(test, table1.text(rows).rstrip(),
                                     ", ".join(f"{r.method.key} {r.action}" for r in runs),
                                     tuple(r.archive for r in runs), fig, time.perf_counter() - t0))
    return out


def table_1(results: str | Path, tests: Sequence[str], out_dir: str | Path | None = None,
            stem: str = "table1") -> tuple[str, Path, Path]:
    """Table 1 from the archives: (text, Markdown file, CSV file)."""
    rows = [table1.read_row(t, m.label, archive_path(results, t, m.key)) for t in tests for m in METHODS]
    md, csv_path = table1.write_table1(rows, results if out_dir is None else out_dir, stem)
    return table1.text(rows), md, csv_path


def figures(results: str | Path, tests: Sequence[str] | None = None) -> list[Path]:
    """Each test's fit figure and particle clouds, Figs. 3-8 on one page and the
    convergence of every run, from the archives."""
    results = Path(results)
    tests = list(tests) if tests else archived_tests(results)
    have = {t: {m.label: archive_path(results, t, m.key) for m in METHODS} for t in tests}
    missing = [str(p) for a in have.values() for p in a.values() if not p.exists()]
    if missing:
        raise RapidCosimError(f"missing archives (run make testN or make table1): {', '.join(missing)}")
    if not have:
        raise RapidCosimError(f"no staged-test archives under {results}; run make table1 first")
    written, fits = [], {}
    for t, archives in have.items():
        fits[t] = load_fits(archives)  # each test loaded (and simulated) once, for all its figures
        title = caption(next(iter(fits[t].runs.values())).experiment)
        written.append(plot_test_fit(fits[t], results / t / f"{t}.png"))
        written.append(plot_particle_clouds(fits[t].runs, results / t / f"{t}-particles.png",
                                            title=f"{title}: particles of the first stage"))
    paper = [t for t in tests if t in PAPER_FIGURE_TESTS]
    if paper:
        written.append(plot_fit_grid([fits[t] for t in paper], results / "figures" / "figs3-8.png",
                                     title="Counterparts of Figs. 3-8: measured pm and both calibrated simulations"))
    written.append(plot_convergence({t: f.runs for t, f in fits.items()}, results / "figures" / "convergence.png"))
    return written


def step_responses(*, results: str | Path, source: ModelSource) -> Path:
    """Every test bench built and simulated on the same staged test, side by side."""
    responses: dict[str, Trajectory] = {}
    for o in source.build(None, log=print):
        sim = Simulator(o.fmu)
        if not sim.inputs:
            responses[o.model.rsplit(".", 1)[-1]] = sim.simulate(STEP_RESPONSE, stop_time=STEP_RESPONSE_STOP,
                                                                 output_interval=0.05)
        sim.close()
    return plot_step_responses(responses, Path(results) / "step_responses.png",
                               title="Step responses of the iGrGen test benches (R = 0.05, Ts = 3 s)")


def demo(config: str | Path, *, results: str | Path, seed: int, engine: EngineSpec, progress: bool,
         source: ModelSource, log=print) -> None:
    """Build the benches, calibrate one staged test with both chains, write its figure
    and its rows of Table 1."""
    t0 = time.perf_counter()
    log("1/3 building the iGrGen test benches (only what changed)")
    source.build(None, log=print)
    log(f"2/3 calibrating {config} with PSO10+NM and PF10+NM (seed {seed}, {engine.n_jobs} workers)")
    (outcome,) = staged_tests([config], results=results, seed=seed, engine=engine, progress=progress, source=source)
    log(describe(outcome))
    log("3/3 Table 1 for this test, from its archives")
    test = outcome.test
    _, md, csv_path = table_1(results, [test], Path(results) / test, f"table1-{test}")
    log(f"\ndemo done in {time.perf_counter() - t0:.0f} s")
    log(f"  figure: {outcome.figure}")
    log(f"  table:  {md} and {csv_path}")
    log("  next:   make table1 (tests 1-8), make figures, make joint")


def describe(o: StagedTestOutcome) -> str:
    return (f"\n{o.test}: {o.actions} ({o.seconds:.1f} s)\n{o.table}\n"
            f"archives: {', '.join(map(str, o.archives))}\nfigure:   {o.figure}")


def joint(tests: Sequence[str], *, experiments: str | Path, results: str | Path, per_test_method: str, seed: int,
          engine: EngineSpec, options: dict | None, progress: bool, source: ModelSource, log=print):
    """The joint SMC fit over ``tests`` and its consistency with each test's own
    optimum (Laplace approximations there); returns the summary and the files written."""
    from ..report.joint import write_joint_report
    from ..calibration.staged import ensure_laplace, laplace_cache, method, run_joint

    method(per_test_method)
    per_test = [archive_path(results, t, per_test_method) for t in tests]
    missing = [str(p) for p in per_test if not p.exists()]
    if missing:
        raise RapidCosimError(f"the consistency check needs the per-test runs first (make table1): "
                              f"{', '.join(missing)}")
    log(f"joint SMC fit of R and Ts over {', '.join(tests)} (seed {seed}, {engine.n_jobs} workers)")
    path, result, action = run_joint([Path(experiments) / t for t in tests], results=results, seed=seed,
                                     engine=engine, options=options, progress=progress, source=source)
    log(f"{path}: {action}, {result.nfev} evaluations, {result.wall_time:.0f} s")
    log("Laplace approximations at each test's optimum")
    laplace = ensure_laplace(per_test, laplace_cache(results), engine=engine, log=log)
    return write_joint_report(path, laplace, Path(results) / "joint")


def diagnosis_report(diagnosis, folder: str | Path, json_path: str | Path | None = None) -> tuple[str, list[Path]]:
    """The diagnosis written as JSON and HDF5 records, ``diagnosis.md`` and its residual
    figure (and the verdict's JSON at ``json_path``); returns the report's text and the
    files."""
    import json

    from ..report.diagnosis import markdown, residual_figure
    from ..report.evidence import evidence_figure

    folder = Path(folder)
    js, h5 = diagnosis.save(folder)
    figure = residual_figure(folder)
    evidence = evidence_figure(folder)
    report = folder / "diagnosis.md"
    report.write_text(markdown(folder))
    files = [report, figure, evidence, js, h5]
    if json_path:
        Path(json_path).parent.mkdir(parents=True, exist_ok=True)
        Path(json_path).write_text(json.dumps(diagnosis.to_json(), indent=2) + "\n")
        files.append(Path(json_path))
    return report.read_text(), files


def structures(configs: Sequence[str | Path], structure_files: Sequence[str | Path], *, holdout: Sequence[str],
               results: str | Path, seed: int, engine: EngineSpec, source: ModelSource,
               log=print) -> tuple[str, list[Path]]:
    """The deliverable part of an identification alone (:func:`rapid_cosim.identify.workflow.deliver`:
    each structure calibrated on the training tests, optional parts freed where they win,
    ranked, each standard record kept and the simplest within the noise recommended), with
    identifiability and the effect catalogue on the winning structure
    (``<results>/structures.md``, ``.json``, ``identifiability.png``)."""
    import json
    from dataclasses import asdict

    from ..structures.structure import Structure
    from ..structures.select import effects_on
    from ..diagnose.workflow import DiagnoseOptions, split_holdout
    from ..identify.workflow import deliver
    from ..experiment import load_experiment
    from ..calibration import RunOptions
    from ..diagnose.context import METHOD
    from ..report.structures import identifiability_figure, markdown

    found = [Structure.load(f) for f in structure_files]  # every file checked before a run starts
    training, heldout = split_holdout([load_experiment(c) for c in configs], holdout)
    results = Path(results)
    results.mkdir(parents=True, exist_ok=True)
    options = RunOptions(method=METHOD, seed=seed, engine=engine)  # the package's own method: nothing to check
    log(f"structures {', '.join(s.name for s in found)} on {', '.join(e.name for e in training)}"
        + (f"; held out: {', '.join(e.name for e in heldout)}" if heldout else ""))
    delivery = deliver(found, training, heldout, workdir=results, options=options, source=source, log=log)
    verdict = delivery.verdict
    if verdict.winner is not None:
        winner = next(s for s in delivery.candidates if s.name == verdict.winner)
        log(f"the effect catalogue on {winner.name}:")
        verdict.effects = effects_on(winner, training, heldout, workdir=results / f"effects-{winner.name}",
                                     options=DiagnoseOptions(seed=seed, engine=engine, write_model=False),
                                     source=source, log=log)
    record = {**verdict.to_json(), "records": [asdict(r) for r in delivery.records],
              "recommended": delivery.recommended, "recommendation": delivery.reason}
    js = results / "structures.json"
    js.write_text(json.dumps(record, indent=2, default=float) + "\n")
    md = results / "structures.md"
    md.write_text(markdown(record))
    png = identifiability_figure(record, results / "identifiability.png")
    return md.read_text(), [md, js, png]



def identification_report(result, folder: str | Path) -> tuple[str, list[Path]]:
    """``<folder>/identification.md`` and ``.json`` of an identification."""
    import json

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    md, js = folder / "identification.md", folder / "identification.json"
    text = result.markdown()
    md.write_text(text)
    js.write_text(json.dumps(result.to_json(), indent=2) + "\n")
    return text, [md, js]
