"""Command line: argument parsing only; each command calls the modules that do the work."""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from . import __version__
from .errors import RapidCosimError


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


def cmd_build(args) -> int:
    from .compiler import build_models

    print(f"building into {args.fmus} (compiler {args.compiler})")
    build_models(args.models or None, package=args.package, fmu_dir=args.fmus, compiler=args.compiler, force=args.force)
    return 0


def cmd_simulate(args) -> int:
    from .compiler import ensure_fmu
    from .simulator import Simulator

    fmu = ensure_fmu(args.model, package=args.package, fmu_dir=args.fmus, compiler=args.compiler)
    sim = Simulator(fmu, timeout=args.timeout)
    outputs = args.outputs.split(",") if args.outputs else None
    traj = sim.simulate(_assignments(args.set), stop_time=args.stop_time, output_interval=args.output_interval,
                        outputs=outputs)
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


def cmd_benches(args) -> int:
    from .compiler import build_models
    from .report.figures import plot_step_responses
    from .simulator import Simulator

    print("1/2 building the iGrGen test benches")
    outcomes = build_models(package=args.package, fmu_dir=args.fmus, compiler=args.compiler)
    print("2/2 simulating a staged test (MCR 60 %, df = -200 mHz at 10 s, back at 60 s) on every bench")
    responses = {}
    for o in outcomes:
        sim = Simulator(o.fmu)
        if sim.inputs:
            continue
        responses[o.model.rsplit(".", 1)[-1]] = sim.simulate(
            {"gov.Ts": 3.0, "src.t_return": 60.0}, stop_time=110.0, output_interval=0.05)
    fig = plot_step_responses(responses, Path(args.results) / "step_responses.png",
                              title="Step responses of the iGrGen test benches (R = 0.05, Ts = 3 s)")
    print(f"figure: {fig}")
    return 0


def _staged_tests(args, experiments) -> list[str]:
    """Run both chains on each staged test; print a short table; write each fit figure."""
    import time

    from .report import table1
    from .report.fits import plot_test_fit
    from .staged import run_staged_test

    tests = []
    for config in experiments:
        t0 = time.perf_counter()
        runs = run_staged_test(config, results=args.results, seed=args.seed, n_jobs=args.n_jobs,
                               progress=not args.quiet, fmu_dir=args.fmus, package=args.package, compiler=args.compiler)
        test = runs[0].test
        rows = [table1.read_row(r.test, r.method.label, r.archive) for r in runs]
        fig = plot_test_fit({r.method.label: r.archive for r in runs}, Path(args.results) / test / f"{test}.png")
        done = ", ".join(f"{r.method.key} {r.action}" for r in runs)
        print(f"\n{test}: {done} ({time.perf_counter() - t0:.1f} s)\n" + table1.text(rows).rstrip())
        print(f"archives: {', '.join(str(r.archive) for r in runs)}\nfigure:   {fig}")
        tests.append(test)
    return tests


def cmd_staged_test(args) -> int:
    _staged_tests(args, args.experiments)
    return 0


def _table1(results, tests, out_dir=None, stem="table1") -> tuple[str, Path, Path]:
    from .report import table1
    from .staged import METHODS, archive_path

    rows = [table1.read_row(t, m.label, archive_path(results, t, m.key)) for t in tests for m in METHODS]
    md, csv_path = table1.write_table1(rows, results if out_dir is None else out_dir, stem)
    return table1.text(rows), md, csv_path


def cmd_table1(args) -> int:
    from .staged import parse_tests

    text, md, csv_path = _table1(args.results, parse_tests(args.tests))
    print(text, end="")
    print(f"\ntable: {md} (Markdown), {csv_path} (CSV)")
    return 0


def cmd_demo(args) -> int:
    import time

    from .compiler import build_models

    t0 = time.perf_counter()
    print("1/3 building the iGrGen test benches (only what changed)")
    build_models(package=args.package, fmu_dir=args.fmus, compiler=args.compiler)
    config = Path(args.experiments) / args.test
    print(f"2/3 calibrating {config} with PSO10+NM and PF10+NM (seed {args.seed}, {args.n_jobs} workers)")
    test = _staged_tests(args, [config])[0]
    print("3/3 Table 1 for this test, from its archives")
    _, md, csv_path = _table1(args.results, [test], Path(args.results) / test, f"table1-{test}")
    print(f"\ndemo done in {time.perf_counter() - t0:.0f} s")
    print(f"  figure: {Path(args.results) / test / (test + '.png')}")
    print(f"  table:  {md} and {csv_path}")
    print("  next:   make table1 (tests 1-8), make figures, make joint")
    return 0


def cmd_figures(args) -> int:
    from .report.archives import caption
    from .report.fits import load_fits, plot_fit_grid, plot_test_fit
    from .report.search import plot_convergence, plot_particle_clouds
    from .staged import METHODS, archive_path, archived_tests, parse_tests

    results = Path(args.results)
    if args.tests:
        tests = parse_tests(args.tests)
    else:
        tests = archived_tests(results)
    have = {t: {m.label: archive_path(results, t, m.key) for m in METHODS} for t in tests}
    missing = [str(p) for a in have.values() for p in a.values() if not p.exists()]
    if missing:
        print(f"rapid-cosim figures: missing archives (run make testN or make table1): {', '.join(missing)}",
              file=sys.stderr)
        return 2
    if not have:
        print(f"rapid-cosim figures: no staged-test archives under {results}; run make table1 first", file=sys.stderr)
        return 2
    written = []
    fits = {}  # each test loaded (and simulated) once, for all its figures
    for t, archives in have.items():
        fits[t] = load_fits(archives)
        title = caption(next(iter(fits[t].runs.values())).experiment)
        written.append(plot_test_fit(fits[t], results / t / f"{t}.png"))
        written.append(plot_particle_clouds(fits[t].runs, results / t / f"{t}-particles.png",
                                            title=f"{title}: particles of the first stage"))
    paper = [t for t in tests if t in [f"test{k}" for k in range(1, 7)]]
    if paper:
        written.append(plot_fit_grid([fits[t] for t in paper], results / "figures" / "figs3-8.png",
                                     title="Counterparts of Figs. 3-8: measured pm and both calibrated simulations"))
    written.append(plot_convergence({t: f.runs for t, f in fits.items()}, results / "figures" / "convergence.png"))
    for w in written:
        print(f"wrote {w}")
    return 0


def cmd_joint(args) -> int:
    from .report.joint import markdown, write_joint_report
    from .staged import archive_path, ensure_laplace, laplace_cache, method, parse_tests, run_joint

    tests = parse_tests(args.tests)
    configs = [Path(args.experiments) / t for t in tests]
    per_test = [archive_path(args.results, t, args.per_test_method) for t in tests]
    missing = [str(p) for p in per_test if not p.exists()]
    if missing:
        raise RapidCosimError(f"the consistency check needs the per-test runs first (make table1): "
                              f"{', '.join(missing)}")
    method(args.per_test_method)
    print(f"joint SMC fit of R and Ts over {', '.join(tests)} (seed {args.seed}, {args.n_jobs} workers)")
    from .calibration import parse_option_overrides

    options = parse_option_overrides(args.option) if args.option else None
    path, result, action = run_joint(configs, results=args.results, seed=args.seed, n_jobs=args.n_jobs,
                                     options=options, progress=not args.quiet, fmu_dir=args.fmus, package=args.package,
                                     compiler=args.compiler)
    print(f"{path}: {action}, {result.nfev} evaluations, {result.wall_time:.0f} s")
    print("Laplace approximations at each test's optimum")
    laplace = ensure_laplace(per_test, laplace_cache(args.results), n_jobs=args.n_jobs)
    summary, md, js, png = write_joint_report(path, laplace, Path(args.results) / "joint")
    print()
    print(markdown(summary))
    print(f"written: {md}, {js}, {png}")
    return 0


def cmd_diagnose(args) -> int:
    import json

    from .diagnose.workflow import DiagnoseOptions, diagnose
    from .experiment import load_experiment
    from .report.diagnosis import markdown, residual_figure

    experiments = [load_experiment(c) for c in args.configs]
    names = [e.name for e in experiments]
    unknown = [h for h in args.holdout or [] if h not in names]
    if unknown:
        raise RapidCosimError(f"--holdout {', '.join(unknown)}: not among the experiments ({', '.join(names)})")
    training = [e for e in experiments if e.name not in (args.holdout or [])]
    heldout = [e for e in experiments if e.name in (args.holdout or [])]
    candidates = tuple(args.candidates.split(",")) if args.candidates else DiagnoseOptions().candidates
    from .diagnose.catalogue import CATALOGUE

    wrong = [c for c in candidates if c not in CATALOGUE]
    if wrong:
        raise RapidCosimError(f"--candidates {', '.join(wrong)}: not in the catalogue ({', '.join(CATALOGUE)})")
    options = DiagnoseOptions(seed=args.seed, n_jobs=args.n_jobs, threshold=args.threshold,
                              max_effects=args.max_effects, candidates=candidates,
                              write_model=not args.no_write_model, model_name=args.model_name)
    folder = Path(args.results)
    diagnosis = diagnose(training, heldout, workdir=folder, options=options, package=args.package,
                         fmu_dir=args.fmus)
    js, h5 = diagnosis.save(folder)
    figure = residual_figure(folder)
    report = folder / "diagnosis.md"
    report.write_text(markdown(folder))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(diagnosis.to_json(), indent=2) + "\n")
    print()
    print(report.read_text())
    print(f"written: {report}, {figure}, {js}, {h5}" + (f", {args.json}" if args.json else ""))
    return 0


def _result_table(result, labels=None) -> str:
    labels = labels or {}
    lines = [f"method {result.method}: best fitness {result.fun:.6g} after {result.nfev} simulations, "
             f"{result.nit} iterations, {result.wall_time:.1f} s ({result.n_failed} failed)",
             f"stop: {result.stop_reason}", "", f"  {'parameter':24s} {'estimate':>12s}"]
    post = result.uncertainty
    if post is not None:
        lines[-1] += f"  {'posterior mean':>14s}  {int(round(100 * post.level))} % credible interval"
    for k, name in enumerate(result.names):
        row = f"  {labels.get(name, name):24s} {result.x[k]:12.6g}"
        if post is not None:
            row += f"  {post.mean[k]:14.6g}  [{post.interval[k, 0]:.6g}, {post.interval[k, 1]:.6g}]"
        lines.append(row)
    return "\n".join(lines)


def _run_options(args, estimator_options):
    from .calibration import RunOptions

    return RunOptions(method=args.method, seed=args.seed, n_jobs=args.n_jobs, backend=args.joblib_backend,
                      estimator_options=estimator_options, runner=args.runner)


def cmd_estimate(args) -> int:
    from datetime import datetime

    from .calibration import inputs_from_configs, parse_option_overrides, start_run

    inputs = inputs_from_configs(args.configs, package=args.package, fmu_dir=args.fmus, compiler=args.compiler)
    options = _run_options(args, parse_option_overrides(args.option))
    archive = args.archive or str(Path(args.results) / f"run-{datetime.now():%Y%m%d-%H%M%S}.h5")
    names = ", ".join(e.name for e in inputs.experiments)
    print(f"estimating {', '.join(inputs.problem.labels)} on {names} with {options.method} "
          f"(seed {options.seed}, n_jobs {options.n_jobs}); archive: {archive}")
    result = start_run(inputs, options, archive, progress=not args.quiet)
    print(_result_table(result, dict(zip(inputs.problem.names, inputs.problem.labels))))
    print(f"\narchive: {archive}")
    return 0


def cmd_resume(args) -> int:
    from .calibration import resume_run

    result = resume_run(args.archive, n_jobs=args.n_jobs, progress=not args.quiet)
    print(_result_table(result))
    return 0


def cmd_rerun(args) -> int:
    from .calibration import rerun

    report = rerun(args.archive, n_jobs=args.n_jobs, progress=not args.quiet)
    print(_result_table(report.result))
    if report.identical:
        print(f"\nidentical: all {report.iterations_compared} iterations and the result match the archive bit for bit "
              f"({report.simulations} simulations re-run)")
        return 0
    print(f"\nDIFFERENT from the archive: {report.first_difference}")
    return 1


def cmd_show(args) -> int:
    import json

    from .calibration import summary_json

    summary = summary_json(args.archive)
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=2) + "\n")
    print(f"{summary['path']}: {summary['method']} (seed {summary['seed']}) on {', '.join(summary['experiments'])}, "
          f"{summary['status']}")
    print(f"  {summary['n_iterations']} iterations, {summary['nfev']} simulations ({summary['n_failed']} failed)"
          + (f", {summary['wall_time']:.1f} s" if summary.get("wall_time") else ""))
    print(f"  best fitness {summary['best_fitness']:.6g}")
    for name, value in summary["best"].items():
        line = f"  {name:24s} {value:.6g}"
        post = summary.get("posterior")
        if post:
            lo, hi = post["interval"][name]
            line += f"   mean {post['mean'][name]:.6g}, {int(round(100 * post['level']))} % interval [{lo:.6g}, {hi:.6g}]"
        print(line)
    if summary.get("stop_reason"):
        print(f"  stop: {summary['stop_reason']}")
    if args.json:
        print(f"written: {args.json}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rapid-cosim", description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--version", action="version", version=f"rapid-cosim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    def model_options(p):
        p.add_argument("--package", default="modelica/iGrGen", help="Modelica package directory (default %(default)s)")
        p.add_argument("--fmus", default="fmus", help="FMU directory (default %(default)s)")
        p.add_argument("--compiler", default="auto", choices=["auto", "openmodelica", "embedded"],
                       help="Modelica-to-FMU compiler; auto = OpenModelica where omc exists (default %(default)s)")

    p = sub.add_parser("build", help="compile test benches into FMUs (only what changed)")
    p.add_argument("models", nargs="*", help="class names; default: every model in <package>.TestBenches")
    p.add_argument("--force", action="store_true", help="rebuild even if up to date")
    model_options(p)
    p.set_defaults(func=cmd_build)

    p = sub.add_parser("simulate", help="simulate one model and write time and outputs as CSV")
    p.add_argument("model", help="class name (built on demand) or path to an .fmu")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="parameter value (repeatable)")
    p.add_argument("--stop-time", type=float, required=True)
    p.add_argument("--output-interval", type=float, default=0.05)
    p.add_argument("--outputs", help="comma-separated variables to record (default: the model's outputs)")
    p.add_argument("--timeout", type=float, default=None, help="wall-clock limit in seconds")
    p.add_argument("--out", help="CSV file (default: standard output)")
    model_options(p)
    p.set_defaults(func=cmd_simulate)

    def run_options(p):
        p.add_argument("--n-jobs", type=int, default=1, help="worker processes (-1: all cores; default %(default)s)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")

    p = sub.add_parser("estimate", help="calibrate parameters against one or more experiments (joint fit)")
    p.add_argument("configs", nargs="+", help="experiment config files (config.toml) or their folders")
    p.add_argument("--method", default="pf:10+nm", help="estimator chain, e.g. pf:10+nm, pso:10+nm, smc, gd "
                   "(default %(default)s)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--option", action="append", metavar="METHOD.NAME=VALUE",
                   help="estimator option, e.g. pf.n_particles=100 (repeatable)")
    p.add_argument("--joblib-backend", default="loky", choices=["loky", "multiprocessing", "threading", "dask"],
                   help="joblib backend; 'dask' needs a running dask.distributed Client (default %(default)s)")
    p.add_argument("--runner", default="compiled", choices=["compiled", "python"],
                   help="simulation runner: the compiled batch runner, or the Python reference loop "
                        "(default %(default)s; the archive records it, and rerun/resume use it)")
    p.add_argument("--archive", help="HDF5 archive to write (default results/run-<time>.h5)")
    p.add_argument("--results", default="results")
    run_options(p)
    model_options(p)
    p.set_defaults(func=cmd_estimate)

    p = sub.add_parser("resume", help="continue an interrupted run from its archive")
    p.add_argument("archive")
    p.add_argument("--n-jobs", type=int, default=None, help="worker processes (default: as archived)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_resume)

    p = sub.add_parser("rerun", help="re-run an archived run from the archive alone and compare bit for bit")
    p.add_argument("archive")
    p.add_argument("--n-jobs", type=int, default=None, help="worker processes (default: as archived)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_rerun)

    p = sub.add_parser("show", help="summarise an archived run")
    p.add_argument("archive")
    p.add_argument("--json", metavar="FILE", help="also write the summary as JSON (best parameters under 'best')")
    p.set_defaults(func=cmd_show)

    p = sub.add_parser("benches", help="build the FMUs and plot every test bench's step response")
    p.add_argument("--results", default="results", help="output directory (default %(default)s)")
    model_options(p)
    p.set_defaults(func=cmd_benches)

    def staged_options(p, n_jobs=2):
        p.add_argument("--results", default="results", help="results folder (default %(default)s)")
        p.add_argument("--seed", type=int, default=1, help="random seed of both chains (default %(default)s)")
        p.add_argument("--n-jobs", type=int, default=n_jobs, help="worker processes (default %(default)s)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        model_options(p)

    p = sub.add_parser("staged-test", help="calibrate staged tests with PSO10+NM and PF10+NM (archived, "
                       "make-like) and draw each test's fit figure")
    p.add_argument("experiments", nargs="+", help="experiment folders or configs, e.g. experiments/test1")
    staged_options(p)
    p.set_defaults(func=cmd_staged_test)

    p = sub.add_parser("table1", help="Table 1 of the paper (Markdown + CSV) from the staged-test archives")
    p.add_argument("--results", default="results", help="results folder (default %(default)s)")
    p.add_argument("--tests", default="1-8", help="tests, e.g. 1-8 or 1,3,9-10 (default %(default)s)")
    p.set_defaults(func=cmd_table1)

    p = sub.add_parser("figures", help="fit figures (Figs. 3-8), convergence and particle clouds from the archives")
    p.add_argument("--results", default="results", help="results folder (default %(default)s)")
    p.add_argument("--tests", help="tests, e.g. 1-8 (default: every test with archives under --results)")
    p.set_defaults(func=cmd_figures)

    p = sub.add_parser("joint", help="joint Bayesian (SMC) fit of R and Ts over several tests, with a "
                       "consistency check of the per-test estimates")
    p.add_argument("--tests", default="1-8", help="tests (default %(default)s)")
    p.add_argument("--experiments", default="experiments", help="experiments folder (default %(default)s)")
    p.add_argument("--per-test-method", default="pf10+nm",
                   help="whose per-test optima are checked against the joint fit (default %(default)s)")
    p.add_argument("--option", action="append", metavar="smc.NAME=VALUE",
                   help="SMC option instead of the defaults (100 particles, 2 moves per stage), e.g. "
                        "smc.n_particles=200 (repeatable)")
    staged_options(p)
    p.set_defaults(func=cmd_joint)

    p = sub.add_parser("diagnose", help="find what the base model misses: try each named effect, rank, "
                       "write the winner into the Modelica package and re-calibrate")
    p.add_argument("configs", nargs="+", help="experiment configs (or their folders)")
    p.add_argument("--holdout", action="append", metavar="EXPERIMENT",
                   help="experiment kept out of the fits to confirm the verdict (repeatable)")
    p.add_argument("--candidates", help="comma-separated effects to try (default: the whole catalogue)")
    p.add_argument("--max-effects", type=int, default=2, help="effects to add greedily (default %(default)s)")
    p.add_argument("--threshold", type=float, default=10.0,
                   help="BIC difference that counts as decisive (default %(default)s)")
    p.add_argument("--no-write-model", action="store_true",
                   help="do not write the named model into the package (nor re-calibrate with it)")
    p.add_argument("--model-name", help="class of the model written (default iGrGen.Diagnosed.Calibrated<Effects>)")
    p.add_argument("--results", default="results/diagnose", help="work and report folder (default %(default)s)")
    p.add_argument("--json", metavar="FILE", help="also write the verdict as JSON here")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--n-jobs", type=int, default=1, help="worker processes (default %(default)s)")
    model_options(p)
    p.set_defaults(func=cmd_diagnose)

    p = sub.add_parser("demo", help="build the FMUs, calibrate one staged test with both chains, "
                       "write its figure and table")
    p.add_argument("--test", default="test1", help="staged test (default %(default)s)")
    p.add_argument("--experiments", default="experiments", help="experiments folder (default %(default)s)")
    staged_options(p)
    p.set_defaults(func=cmd_demo)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"warning: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    import warnings

    args = build_parser().parse_args(argv)
    with warnings.catch_warnings():  # restores the filters and showwarning on exit
        # a user wants each warning once, as a sentence, not the source line that raised it
        warnings.filterwarnings("once", category=UserWarning)
        warnings.showwarning = _show_warning
        try:
            return args.func(args)
        except RapidCosimError as e:
            print(f"rapid-cosim {args.command}: error: {e}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print("interrupted", file=sys.stderr)
            return 130


if __name__ == "__main__":
    sys.exit(main())
