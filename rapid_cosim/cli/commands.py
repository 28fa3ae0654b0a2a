"""The commands: each reads its arguments, calls the Python API (:mod:`rapid_cosim.api`)
or the staged-test campaign (:mod:`rapid_cosim.cli.campaign`) and prints what it returns;
the parser that names them is :mod:`rapid_cosim.cli.parser`."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

from ..compiler.source import ModelSource
from ..errors import RapidCosimError
from ..fitting.engine import EngineSpec


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


def _source(args) -> ModelSource:
    """The models of ``--package``, ``--fmus`` and ``--compiler`` (the parser's ``model_options``)."""
    return ModelSource(args.package, args.fmus, args.compiler).check()


def _engine(args, *, cluster: bool = False) -> EngineSpec:
    """The engine of ``--n-jobs``, ``--joblib-backend`` and ``--scheduler`` (the parser's
    ``engine_options``; a command with ``--n-jobs`` alone gets the default backend, the
    fleet, ``cluster``, dask's), checked here, before anything is read: the one place the
    CLI builds an engine."""
    kind = "dask" if cluster else getattr(args, "joblib_backend", EngineSpec.backend)
    return EngineSpec(args.n_jobs, kind, getattr(args, "scheduler", None))


def _archived_engine(args):
    """The archived engine with each setting the command line gives over it (None: the
    archived one), applied where the archive is read."""
    if args.n_jobs is None and args.joblib_backend is None and args.scheduler is None:
        return None
    return lambda archived: archived.overridden(args.n_jobs, args.joblib_backend, args.scheduler)


def cmd_build(args) -> int:
    source = _source(args)
    print(f"building into {source.fmu_path} (compiler {args.compiler})")
    source.build(args.models or None, log=print, force=args.force)
    return 0


def cmd_simulate(args) -> int:
    from ..api import simulate

    traj = simulate(args.model, _assignments(args.set), stop_time=args.stop_time,
                    output_interval=args.output_interval, outputs=args.outputs.split(",") if args.outputs else None,
                    timeout=args.timeout, runner=args.runner, communication_step=args.communication_step,
                    source=_source(args))
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
    from ..api import as_experiments, calibrate_with, default_archive
    from ..archive.writer import refuse_existing
    from ..calibration import RunOptions, parse_option_overrides
    from ..experiment.electrical import describe_recording
    from ..identify.check import quietly, say, unsaid

    run_options = RunOptions(method=args.method, seed=args.seed, engine=_engine(args), runner=args.runner,
                             estimator_options=parse_option_overrides(args.option)).check()
    archive = Path(args.archive) if args.archive else default_archive(args.results)
    refuse_existing(archive)  # before the recordings are read
    notes: list = []  # what reading warned of: said once, with the recordings' lines or after them
    experiments = quietly(lambda: as_experiments(args.configs), notes)  # checked before anything is announced
    print(f"estimating on {', '.join(e.name for e in experiments)} with {args.method} (seed {args.seed}, "
          f"n_jobs {args.n_jobs})")
    for words in filter(None, map(describe_recording, experiments)):
        print(f"  {words}")
    for exp in experiments:
        for line in exp.recording.lines():
            print(f"  {exp.name}: {line}")
    say(unsaid(notes, experiments))
    fit = calibrate_with(experiments, run_options, archive=archive, progress=not args.quiet, source=_source(args))
    print(fit)
    print(f"\narchive: {archive}")
    return 0


def cmd_resume(args) -> int:
    from ..api import resume

    print(resume(args.archive, engine=_archived_engine(args), progress=not args.quiet))
    return 0


def cmd_rerun(args) -> int:
    from ..api import rerun

    fit = rerun(args.archive, engine=_archived_engine(args), progress=not args.quiet)
    print(fit)
    if fit.identical and not fit.finished:
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
    return {"results": args.results, "seed": args.seed, "engine": _engine(args), "progress": not args.quiet,
            "source": _source(args)}


def cmd_staged_test(args) -> int:
    from .campaign import describe, staged_tests

    for outcome in staged_tests(args.experiments, **_campaign(args)):
        print(describe(outcome))
    return 0


def cmd_report(args) -> int:
    from ..report.html import validation_page
    from ..validation.tolerances import LABELS, verdict

    page = validation_page(args.archive, args.out, engine=_engine(args), tolerances=args.tolerances,
                           heldout=args.holdout or (), diagnosis=args.diagnosis, pdf=args.pdf or None, bus=args.bus,
                           machine_id=args.id, mva=args.mva, source=_source(args))
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
    print(f"figure: {step_responses(results=args.results, source=_source(args))}")
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
    from ..api import as_experiments, diagnose_with
    from .campaign import diagnosis_report
    from ..diagnose.workflow import DiagnoseOptions, split_holdout

    options = {"threshold": args.threshold, "max_effects": args.max_effects, "model_name": args.model_name}
    if args.candidates:
        options["candidates"] = tuple(args.candidates.split(","))
    checked = DiagnoseOptions(seed=args.seed, engine=_engine(args), write_model=not args.no_write_model,
                              **options)  # refused before anything is read or written
    training, heldout = split_holdout(as_experiments(args.configs), args.holdout or [])
    from ..identify.result import recording_story

    for line in recording_story({e.name: e.recording.summary() for e in (*training, *heldout)}):
        print(line)
    diagnosis = diagnose_with(training, checked, heldout=heldout, workdir=args.results, source=_source(args))
    text, files = diagnosis_report(diagnosis, args.results, args.json)
    print()
    print(text)
    print(f"written: {', '.join(map(str, files))}")
    return 0


def cmd_structures(args) -> int:
    from .campaign import structures

    text, files = structures(args.configs, args.structures.split(","), holdout=args.holdout or [],
                             results=args.results, seed=args.seed, engine=_engine(args), source=_source(args))
    print()
    print(text)
    print(f"written: {', '.join(map(str, files))}")
    return 0


def cmd_identify(args) -> int:
    from ..api import identify
    from ..progress import StagedLog
    from .campaign import identification_report

    log = StagedLog()
    try:
        result = identify(args.unit, workdir=args.results, seed=args.seed, engine=_engine(args), source=_source(args),
                          mva=args.mva, report=not args.no_report, pdf=not args.no_pdf, log=log)
    finally:
        log.close()
    _, files = identification_report(result, args.results)
    print()
    print(result.story(also=files))
    return 0


def cmd_fleet(args) -> int:
    from ..fleet import Route, run_fleet

    result = run_fleet(args.fleet, results=args.results, engine=_engine(args, cluster=True),
                       seed=args.seed, source=_source(args), pdf=args.pdf, check_only=args.check_only,
                       progress=not args.quiet)
    print(f"\n{result.summary()} ({result.seconds:.0f} s, {len(result.kept)} kept from an earlier run)")
    for u in result.units:
        if u.route is Route.FAILED:
            print(f"  {u.unit}: failed: {u.error}")
    print("written: " + ", ".join(result.files.values()))
    return 100 + min(result.failed, 155) if result.failed else 0


def cmd_check(args) -> int:
    from ..check import check

    reports = [check(path, method=args.method, source=_source(args)) for path in args.paths]
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
