"""Command line: argument parsing over the Python API (:mod:`rapid_cosim.api`) and the
staged-test campaign (:mod:`rapid_cosim.cli.campaign`); every command calls one of them and
prints what it returns.

Kept whole (over 400 lines): one short parser per command; split, the commands' help
would scatter.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

from ..version import __version__
from ..errors import RapidCosimError, RunInterrupted

PACKAGE_HELP = "Modelica package folder (default: the iGrGen shipped with rapid-cosim, or $RAPID_COSIM_PACKAGE)"
FMUS_HELP = "folder the FMUs are built into (default: the user's cache, or $RAPID_COSIM_FMUS)"


def _assignments(items: list[str]) -> dict[str, float]:
    values = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise RapidCosimError(f"--set expects NAME=VALUE, got {item!r}")
        try:
            values[name.strip()] = float(value)
        except ValueError:
            raise RapidCosimError(f"--set {name.strip()}: {value!r} is not a number") from None
    return values


def _models(args) -> dict:
    return {"package": args.package, "fmu_dir": args.fmus, "compiler": args.compiler}


def cmd_build(args) -> int:
    from ..compiler import build_models, resolve_models

    print(f"building into {resolve_models(args.package, args.fmus)[1]} (compiler {args.compiler})")
    build_models(args.models or None, package=args.package, fmu_dir=args.fmus, compiler=args.compiler,
                 force=args.force)
    return 0


def cmd_simulate(args) -> int:
    from ..api import simulate

    traj = simulate(args.model, _assignments(args.set), stop_time=args.stop_time,
                    output_interval=args.output_interval, outputs=args.outputs.split(",") if args.outputs else None,
                    timeout=args.timeout, runner=args.runner, communication_step=args.communication_step,
                    **_models(args))
    names = list(traj.outputs)
    out = open(args.out, "w", newline="") if args.out else sys.stdout
    try:
        writer = csv.writer(out)
        writer.writerow(["time", *names])
        for k, t in enumerate(traj.time):
            writer.writerow([f"{t:.6g}", *(repr(float(traj[n][k])) for n in names)])
    finally:
        if args.out:
            out.close()
            print(f"wrote {len(traj.time)} rows of time, {', '.join(names)} to {args.out}")
    return 0


def cmd_estimate(args) -> int:
    from ..api import as_experiments, calibrate, default_archive
    from ..calibration import RunOptions, parse_option_overrides
    from ..experiment.electrical import describe_recording

    options = parse_option_overrides(args.option)
    RunOptions(method=args.method, seed=args.seed, n_jobs=args.n_jobs, backend=args.joblib_backend,
               runner=args.runner, scheduler=args.scheduler, estimator_options=options).check()
    experiments = as_experiments(args.configs)  # every option and config checked before anything is announced
    archive = Path(args.archive) if args.archive else default_archive(args.results)
    print(f"estimating on {', '.join(e.name for e in experiments)} with {args.method} (seed {args.seed}, "
          f"n_jobs {args.n_jobs})")
    for words in filter(None, map(describe_recording, experiments)):
        print(f"  {words}")
    for exp in experiments:
        for line in exp.recording.lines():
            print(f"  {exp.name}: {line}")
    fit = calibrate(experiments, args.method, seed=args.seed, n_jobs=args.n_jobs, archive=archive, options=options,
                    runner=args.runner, joblib_backend=args.joblib_backend, scheduler=args.scheduler,
                    progress=not args.quiet, **_models(args))
    print(fit)
    print(f"\narchive: {archive}")
    return 0


def cmd_resume(args) -> int:
    from ..api import resume

    print(resume(args.archive, n_jobs=args.n_jobs, joblib_backend=args.joblib_backend, scheduler=args.scheduler,
                 progress=not args.quiet))
    return 0


def cmd_rerun(args) -> int:
    from ..api import rerun

    fit = rerun(args.archive, n_jobs=args.n_jobs, joblib_backend=args.joblib_backend, scheduler=args.scheduler,
                progress=not args.quiet)
    print(fit)
    if fit.identical and "unfinished" in fit.message:
        print("\nidentical as far as the archive goes: its iterations match the re-run bit for bit; "
              f"the run was unfinished ('rapid-cosim resume {args.archive}' finishes it)")
        return 0
    if fit.identical:
        print(f"\nidentical: all {fit.nit} iterations and the result match the archive bit for bit")
        return 0
    print(f"\nDIFFERENT from the archive: {fit.message}")
    return 1


def cmd_show(args) -> int:
    from ..calibration import summary_json
    from ..report.tables import summary_text

    summary = summary_json(args.archive)
    print(summary_text(summary))
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=2) + "\n")
        print(f"written: {args.json}")
    if summary["damaged"]:
        raise RapidCosimError(summary["damaged"][0])
    return 0


def cmd_verify(args) -> int:
    from ..archive.verify import verify

    checks = verify(args.archive)
    for c in checks:
        print(f"  {'ok     ' if c.intact else 'DAMAGED'} {c.part}" + (f": {c.detail}" if c.detail else ""))
    damaged = [c for c in checks if not c.intact]
    if damaged:
        print(f"{args.archive}: damaged ({len(damaged)} of {len(checks)} parts)")
        return 1
    print(f"{args.archive}: intact ({len(checks)} parts checked)")
    return 0


def _campaign(args) -> dict:
    return {"results": args.results, "seed": args.seed, "n_jobs": args.n_jobs, "progress": not args.quiet,
            **_models(args)}


def cmd_staged_test(args) -> int:
    from .campaign import describe, staged_tests

    for outcome in staged_tests(args.experiments, **_campaign(args)):
        print(describe(outcome))
    return 0


def cmd_report(args) -> int:
    from ..report.html import validation_page
    from ..report.tolerances import LABELS, verdict

    page = validation_page(args.archive, args.out, n_jobs=args.n_jobs, tolerances=args.tolerances,
                           heldout=args.holdout or (), diagnosis=args.diagnosis, pdf=args.pdf or None, bus=args.bus,
                           machine_id=args.id, mva=args.mva, package=args.package, fmu_dir=args.fmus)
    print(f"{page.path}: {page.n_figures} figure(s); per test the error metrics against the tolerance bands")
    for m, checks in zip(page.metrics, page.checks):
        failed = [LABELS[c.metric] for c in checks if c.passed is False]
        result = {True: "pass", False: "FAIL", None: "n/a"}[verdict(checks)]
        print(f"  {m.experiment:<10} {m.role:<9} {result:<4}  RMSE {m.rmse:.3g}  settled change error "
              f"{m.settled_error:+.3g}" + (f"  outside: {', '.join(failed)}" if failed else ""))
    print(f"record: {page.record.model or 'none'}" + ("" if page.record.model else f" ({page.record.note})"))
    if page.pdf:
        print(f"PDF: {page.pdf}")
    return 0


def cmd_table1(args) -> int:
    from .campaign import table_1
    from ..calibration.staged import parse_tests

    text, md, csv_path = table_1(args.results, parse_tests(args.tests))
    print(text, end="")
    print(f"\ntable: {md} (Markdown), {csv_path} (CSV)")
    return 0


def cmd_figures(args) -> int:
    from .campaign import figures
    from ..calibration.staged import parse_tests

    for path in figures(args.results, parse_tests(args.tests) if args.tests else None):
        print(f"wrote {path}")
    return 0


def cmd_benches(args) -> int:
    from .campaign import step_responses

    print("building the iGrGen test benches and simulating a staged test (MCR 60 %, df = -200 mHz at 10 s, "
          "back at 60 s) on each")
    print(f"figure: {step_responses(results=args.results, **_models(args))}")
    return 0


def cmd_joint(args) -> int:
    from ..calibration import parse_option_overrides
    from .campaign import joint
    from ..report.joint import markdown
    from ..calibration.staged import parse_tests

    options = parse_option_overrides(args.option) if args.option else None
    summary, md, js, png = joint(parse_tests(args.tests), experiments=args.experiments,
                                 per_test_method=args.per_test_method, options=options, **_campaign(args))
    print()
    print(markdown(summary))
    print(f"written: {md}, {js}, {png}")
    return 0


def cmd_diagnose(args) -> int:
    from ..api import as_experiments, diagnose
    from .campaign import diagnosis_report
    from ..diagnose.workflow import DiagnoseOptions, split_holdout

    options = {"threshold": args.threshold, "max_effects": args.max_effects, "model_name": args.model_name,
               "backend": args.joblib_backend, "scheduler": args.scheduler}
    if args.candidates:
        options["candidates"] = tuple(args.candidates.split(","))
    DiagnoseOptions(**options)  # refused before anything is read or written
    training, heldout = split_holdout(as_experiments(args.configs), args.holdout or [])
    from ..identify.result import recording_story

    for line in recording_story({e.name: e.recording.summary() for e in (*training, *heldout)}):
        print(line)
    diagnosis = diagnose(training, heldout=heldout, workdir=args.results, seed=args.seed, n_jobs=args.n_jobs,
                         write_model=not args.no_write_model, package=args.package, fmu_dir=args.fmus, **options)
    text, files = diagnosis_report(diagnosis, args.results, args.json)
    print()
    print(text)
    print(f"written: {', '.join(map(str, files))}")
    return 0


def cmd_structures(args) -> int:
    from .campaign import structures

    text, files = structures(args.configs, args.structures.split(","), holdout=args.holdout or [],
                             results=args.results, seed=args.seed, n_jobs=args.n_jobs, package=args.package,
                             fmu_dir=args.fmus, backend=args.joblib_backend, scheduler=args.scheduler)
    print()
    print(text)
    print(f"written: {', '.join(map(str, files))}")
    return 0


def cmd_identify(args) -> int:
    from ..api import identify
    from .campaign import identification_report

    result = identify(args.unit, workdir=args.results, seed=args.seed, n_jobs=args.n_jobs, package=args.package,
                      fmu_dir=args.fmus, backend=args.joblib_backend, scheduler=args.scheduler, mva=args.mva,
                      report=not args.no_report, pdf=not args.no_pdf)
    _, files = identification_report(result, args.results)
    print()
    print(result.story(also=files))
    return 0


def cmd_fleet(args) -> int:
    from ..fleet import run_fleet

    result = run_fleet(args.fleet, results=args.results, workers=args.workers, scheduler=args.scheduler,
                       seed=args.seed, package=args.package, fmu_dir=args.fmus, pdf=args.pdf,
                       check_only=args.check_only, progress=not args.quiet)
    print(f"\n{result.summary()} ({result.seconds:.0f} s, {len(result.kept)} kept from an earlier run)")
    for u in result.units:
        if u["path"] == "failed":
            print(f"  {u['unit']}: failed: {u['error']}")
    print("written: " + ", ".join(result.files.values()))
    return 100 + min(result.failed, 155) if result.failed else 0


def cmd_check(args) -> int:
    from ..check import check

    reports = [check(path, method=args.method, package=args.package, fmu_dir=args.fmus) for path in args.paths]
    print("\n".join(r.text() for r in reports))
    return 0 if all(r.ok for r in reports) else 2


def cmd_export(args) -> int:
    from ..api import export

    written = export(args.archive, args.out, format=args.format, bus=args.bus, machine_id=args.id, mva=args.mva,
                     bus_name=args.bus_name, kv=args.kv)
    print(f"wrote {written.path}: {written.model} of machine {args.id} at bus {args.bus}")
    print(written.text, end="")
    if written.dropped:
        print("not in the record (no field): " + ", ".join(f"{k} = {v:g}" for k, v in written.dropped.items()))
    check = written.reproduction
    print(f"read back and simulated on {', '.join(check.errors)}: reproduces the fit to {check.worst:.1g} pu")
    if (args.format or Path(args.out).suffix.lstrip(".")) == "dyr" and args.mva is not None:
        print("note: a .dyr record carries no base; PSS/E takes the machine's MBASE from the .raw")
    return 0


def cmd_demo(args) -> int:
    from .campaign import demo

    demo(Path(args.experiments) / args.test, **_campaign(args))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rapid-cosim", description="Calibrate Modelica models of power-plant "
                                     "governors against field measurements.")
    parser.add_argument("--version", action="version", version=f"rapid-cosim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    def command(name, func, help):
        p = sub.add_parser(name, help=help)
        p.set_defaults(func=func)
        return p

    def model_options(p):
        p.add_argument("--package", help=PACKAGE_HELP)
        p.add_argument("--fmus", help=FMUS_HELP)
        p.add_argument("--compiler", default="auto", choices=["auto", "openmodelica", "embedded"],
                       help="Modelica-to-FMU compiler; auto = OpenModelica where omc exists (default %(default)s)")

    def runner_option(p):
        from ..simulator import DEFAULT_RUNNER, RUNNERS

        p.add_argument("--runner", default=DEFAULT_RUNNER, choices=list(RUNNERS),
                       help="simulation runner: the exponential integrator (one model evaluation per sample, CVODE "
                            "where its error estimate asks), CVODE in the compiled batch runner, or the Python "
                            "reference loop (default %(default)s; an archive records it, and rerun/resume use it)")

    def campaign_options(p, n_jobs=2):
        p.add_argument("--results", default="results", help="results folder (default %(default)s)")
        p.add_argument("--seed", type=int, default=1, help="random seed of both chains (default %(default)s)")
        p.add_argument("--n-jobs", type=int, default=n_jobs, help="worker processes (default %(default)s)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        model_options(p)

    def selection_options(p, results):  # what diagnose and structures share
        p.add_argument("configs", nargs="+", help="experiment configs (or their folders)")
        p.add_argument("--holdout", action="append", metavar="EXPERIMENT",
                       help="experiment kept out of the fits to confirm the verdict (repeatable)")
        p.add_argument("--results", default=results, help="work and report folder (default %(default)s)")
        p.add_argument("--seed", type=int, default=1)
        p.add_argument("--n-jobs", type=int, default=1, help="worker processes (default %(default)s; with "
                       "--joblib-backend dask, 1 or -1 split each batch over every worker of the cluster)")
        p.add_argument("--joblib-backend", default="loky", choices=["loky", "multiprocessing", "sequential", "dask"],
                       help="where the work goes with --n-jobs > 1: candidates fitted in local processes (loky), or "
                            "their batches on a dask cluster (default %(default)s)")
        p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="a running dask scheduler, with dask")
        model_options(p)

    p = command("build", cmd_build, "compile test benches into FMUs (only what changed)")
    p.add_argument("models", nargs="*", help="class names; default: every model in <package>.TestBenches")
    p.add_argument("--force", action="store_true", help="rebuild even if up to date")
    model_options(p)

    p = command("simulate", cmd_simulate, "simulate one model and write time and outputs as CSV")
    p.add_argument("model", help="class name (built on demand) or path to an .fmu")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="parameter value (repeatable)")
    p.add_argument("--stop-time", type=float, required=True)
    p.add_argument("--output-interval", type=float, default=0.05)
    p.add_argument("--outputs", help="comma-separated variables to record (default: the model's outputs)")
    p.add_argument("--timeout", type=float, default=None, help="wall-clock limit in seconds")
    p.add_argument("--communication-step", type=float, default=None, metavar="SECONDS",
                   help="Co-Simulation FMUs: the largest communication step (the fixed one where the FMU "
                        "cannot vary it); default: the output grid")
    p.add_argument("--out", help="CSV file (default: standard output)")
    runner_option(p)
    model_options(p)

    p = command("estimate", cmd_estimate, "calibrate parameters against one or more experiments (joint fit)")
    p.add_argument("configs", nargs="+", help="experiment config files (config.toml) or their folders")
    p.add_argument("--method", default="pf:10+nm", help="estimator chain, e.g. pf:10+nm, pso:10+nm, smc, gd "
                   "(default %(default)s)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--option", action="append", metavar="METHOD.NAME=VALUE",
                   help="estimator option, e.g. pf.n_particles=100 (repeatable)")
    p.add_argument("--joblib-backend", default="loky", choices=["loky", "multiprocessing", "sequential", "dask"],
                   help="where particles run: local processes (loky), or a dask cluster (default %(default)s)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="a running dask scheduler, with --joblib-backend dask")
    runner_option(p)
    p.add_argument("--archive", help="HDF5 archive to write (default <results>/run-<time>.h5)")
    p.add_argument("--results", default="results")
    p.add_argument("--n-jobs", type=int, default=1, help="worker processes (-1: all cores; default %(default)s; "
                   "with --joblib-backend dask, 1 or -1 split each batch over every worker of the cluster)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    model_options(p)

    for name, func, help in (("resume", cmd_resume, "continue an interrupted run from its archive"),
                             ("rerun", cmd_rerun, "re-run an archived run from the archive alone and compare "
                                                  "bit for bit")):
        p = command(name, func, help)
        p.add_argument("archive")
        p.add_argument("--n-jobs", type=int, default=None, help="worker processes (default: as archived)")
        p.add_argument("--joblib-backend", choices=["loky", "multiprocessing", "sequential", "dask"],
                       help="where particles run (default: as archived; the result does not depend on it)")
        p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="a running dask scheduler")
        p.add_argument("--quiet", action="store_true", help="no progress bar")

    p = command("show", cmd_show, "summarise an archived run")
    p.add_argument("archive")
    p.add_argument("--json", metavar="FILE", help="also write the summary as JSON (best parameters under 'best')")

    p = command("verify", cmd_verify, "check every part of an archive against its checksums")
    p.add_argument("archive")

    p = command("report", cmd_report, "write a finished run's validation page: one self-contained HTML file "
                "with every experiment's traces, error metrics and the parameters with intervals")
    p.add_argument("archive")
    p.add_argument("--out", help="HTML file (default: the archive's name with .html)")
    p.add_argument("--n-jobs", type=int, default=1, help="worker processes for the intervals (default %(default)s)")
    p.add_argument("--tolerances", metavar="FILE", help="TOML file with a [validation] table of tolerance bands "
                   "(default: the project's bands, stated on the page)")
    p.add_argument("--holdout", nargs="+", metavar="CONFIG", help="held-out experiments, predicted at the calibration")
    p.add_argument("--diagnosis", metavar="JSON", help="a diagnosis.json of rapid-cosim diagnose: its verdict and "
                   "adequacy p-values on the page")
    p.add_argument("--pdf", nargs="?", const=True, metavar="FILE", help="also print the page to PDF with headless "
                   "Chromium (default: beside the page)")
    p.add_argument("--bus", type=int, default=1, help="bus number in the records (default %(default)s)")
    p.add_argument("--id", default="1", help="machine id in the records (default %(default)s)")
    p.add_argument("--mva", type=float, help="the machine's MVA base, for the PSLF .dyd record")
    p.add_argument("--package", help=PACKAGE_HELP + "; for the held-out tests' benches")
    p.add_argument("--fmus", help=FMUS_HELP)

    p = command("benches", cmd_benches, "build the FMUs and plot every test bench's step response")
    p.add_argument("--results", default="results", help="output directory (default %(default)s)")
    model_options(p)

    p = command("staged-test", cmd_staged_test, "calibrate staged tests or recorded events with PSO10+NM and "
                "PF10+NM (archived, make-like) and draw each one's fit figure (recorded inputs above)")
    p.add_argument("experiments", nargs="+", help="experiment folders or configs, e.g. experiments/test1")
    campaign_options(p)

    p = command("table1", cmd_table1, "Table 1 of the paper (Markdown + CSV) from the staged-test archives")
    p.add_argument("--results", default="results", help="results folder (default %(default)s)")
    p.add_argument("--tests", default="1-8", help="tests, e.g. 1-8 or 1,3,9-10 (default %(default)s)")

    p = command("figures", cmd_figures, "fit figures (Figs. 3-8), convergence and particle clouds from the archives")
    p.add_argument("--results", default="results", help="results folder (default %(default)s)")
    p.add_argument("--tests", help="tests, e.g. 1-8 (default: every test with archives under --results)")

    p = command("joint", cmd_joint, "joint Bayesian (SMC) fit of R and Ts over several tests, with a "
                "consistency check of the per-test estimates")
    p.add_argument("--tests", default="1-8", help="tests (default %(default)s)")
    p.add_argument("--experiments", default="experiments", help="experiments folder (default %(default)s)")
    p.add_argument("--per-test-method", default="pf10+nm",
                   help="whose per-test optima are checked against the joint fit (default %(default)s)")
    p.add_argument("--option", action="append", metavar="smc.NAME=VALUE",
                   help="SMC option instead of the defaults (100 particles, 2 moves per stage), e.g. "
                        "smc.n_particles=200 (repeatable)")
    campaign_options(p)

    p = command("diagnose", cmd_diagnose, "find what the base model misses: try each named effect, rank, "
                "write the winner into the Modelica package and re-calibrate")
    selection_options(p, "results/diagnose")
    p.add_argument("--candidates", help="comma-separated effects to try (default: the whole catalogue)")
    p.add_argument("--max-effects", type=int, default=2, help="effects to add greedily (default %(default)s)")
    p.add_argument("--threshold", type=float, default=10.0,
                   help="BIC difference that counts as decisive (default %(default)s)")
    p.add_argument("--no-write-model", action="store_true",
                   help="do not write the named model into the package (nor re-calibrate with it)")
    p.add_argument("--model-name", help="class of the model written (default iGrGen.Diagnosed.Calibrated<Effects>)")
    p.add_argument("--json", metavar="FILE", help="also write the verdict as JSON here")

    p = command("structures", cmd_structures, "which governor structure fits the unit: calibrate each, rank "
                "them (BIC, held-out tests, adequacy), say which parameters the tests determine, run the "
                "effect catalogue on the winner")
    selection_options(p, "results/structures")
    p.add_argument("--structures", required=True,
                   help="comma-separated structure files, e.g. experiments/structures/TGTypeI.toml,...")

    p = command("identify", cmd_identify, "one identification per unit: the explanation (TG Type I and the effect "
                "catalogue), every standard record's calibration and fidelity, the recommended record written as "
                "PSS/E .dyr and PSLF .dyd, and its validation report (HTML, PDF)")
    p.add_argument("unit", help="the unit's unit.toml, or its folder")
    p.add_argument("--mva", type=float, help="the machine's MVA base (1 to 5000), over [unit] mva: the PSLF .dyd "
                   "record needs it")
    p.add_argument("--no-report", action="store_true", help="no validation report of the recommended record")
    p.add_argument("--no-pdf", action="store_true", help="the report as HTML only (no headless Chromium)")
    p.add_argument("--results", default="results/identify", help="work and report folder (default %(default)s)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--n-jobs", type=int, default=1, help="worker processes (default %(default)s; with "
                   "--joblib-backend dask, 1 or -1 split each batch over every worker of the cluster)")
    p.add_argument("--joblib-backend", default="loky", choices=["loky", "multiprocessing", "sequential", "dask"],
                   help="where the work goes with --n-jobs > 1 (default %(default)s)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="a running dask scheduler, with dask")
    model_options(p)

    p = command("fleet", cmd_fleet, "many units, one grid event: each unit's record on file played back and judged "
                "against the tolerance bands and the recorder's noise, the units whose record fails identified, on a dask cluster; the fleet's "
                "page, table and records (exit status 100 + the number of units that failed with an error, 0 if none; a "
                "record that fails is a row, not an error)")
    p.add_argument("fleet", help="the fleet file (fleet.toml), or its folder")
    p.add_argument("--results", default="results/fleet", help="results folder (default %(default)s); a rerun there "
                   "keeps every unit whose inputs have not changed")
    p.add_argument("--workers", type=int, default=2, help="local worker processes (default %(default)s)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="a running dask scheduler instead of local workers")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--pdf", action="store_true", help="each identified unit's report as PDF too (headless Chromium)")
    p.add_argument("--check-only", action="store_true", help="play every record on file back and judge it; identify "
                   "nothing (about 2 s a unit; a unit without a record is a failed row)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    model_options(p)

    p = command("check", cmd_check, "load and check everything a run would (configs and their recordings, a unit's "
                "structure files, a fleet's units and records on file) and say what it would do and cost; every "
                "problem at once, each naming its file and key or row; exit status 2 if any")
    p.add_argument("paths", nargs="+", metavar="PATH", help="an experiment config (or its folder), a unit.toml (or "
                   "its folder) or a fleet file")
    p.add_argument("--method", default="pf:10+nm", help="for a config: the estimator chain a calibration would run "
                   "(default %(default)s)")
    model_options(p)

    p = command("export", cmd_export, "write a calibration of TGOV1, IEEEG1, GGOV1 or HYGOV as a PSS/E .dyr or "
                "PSLF .dyd record (values on the machine base; conversions: docs/identify.md, 'Export and import')")
    p.add_argument("archive", help="the calibration's archive (.h5)")
    p.add_argument("--out", required=True, help="record file to write, .dyr or .dyd")
    p.add_argument("--format", choices=["dyr", "dyd"], help="default: by the suffix of --out")
    p.add_argument("--bus", type=int, default=1, help="the machine's bus number (default %(default)s)")
    p.add_argument("--id", default="1", help="the machine id (default %(default)s)")
    p.add_argument("--mva", type=float, help="the machine's MVA base (required for .dyd)")
    p.add_argument("--bus-name", default="", help="the bus name of a .dyd record")
    p.add_argument("--kv", type=float, default=0.0, help="the bus's base kV of a .dyd record (default %(default)s)")

    p = command("demo", cmd_demo, "build the FMUs, calibrate one staged test with both chains, "
                "write its figure and table")
    p.add_argument("--test", default="test1", help="staged test (default %(default)s)")
    p.add_argument("--experiments", default="experiments", help="experiments folder (default %(default)s)")
    campaign_options(p)
    return parser


class _Warnings:
    """Each warning said once, as a sentence (not the source line that raised it); how
    often each recurred is said when the command ends."""

    def __init__(self):
        self.seen: dict[tuple[str, type], int] = {}

    def show(self, message, category, filename, lineno, file=None, line=None) -> None:
        key = (str(message), category)
        self.seen[key] = self.seen.get(key, 0) + 1
        if self.seen[key] == 1:
            print(f"warning: {message}", file=sys.stderr)

    def recurred(self) -> None:
        again = [(text, n) for (text, _), n in self.seen.items() if n > 1]
        for text, n in again:
            print(f"warning said {n} times: {text[:100]}{'...' if len(text) > 100 else ''}", file=sys.stderr)


def _reference(error: RapidCosimError) -> str:
    """Where the reference explains the key an error names (docs/config.md), if it does."""
    from ..errors import ConfigError
    from ..experiment.schema import reference

    link = reference(error.key) if isinstance(error, ConfigError) and error.key else None
    return f"\n  (the key: {link})" if link else ""


def _terminate(signum, frame):
    raise KeyboardInterrupt  # SIGTERM ends a run as Ctrl-C does: archive closed, resumable


def main(argv: list[str] | None = None) -> int:
    import signal
    import threading
    import warnings

    args = build_parser().parse_args(argv)
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    said = _Warnings()
    with warnings.catch_warnings():  # restores the filters and showwarning on exit
        warnings.filterwarnings("always", category=UserWarning)  # counted and said once by _Warnings
        warnings.showwarning = said.show
        try:
            return args.func(args)
        except RunInterrupted as e:
            print(f"rapid-cosim {args.command}: {e}", file=sys.stderr)
            return 130
        except RapidCosimError as e:
            print(f"rapid-cosim {args.command}: error: {e}{_reference(e)}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
            return 130
        finally:
            said.recurred()
            if main_thread:
                signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
