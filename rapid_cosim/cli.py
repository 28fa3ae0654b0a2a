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
    from .build import build_models

    print(f"building into {args.fmus} (backend {args.backend})")
    build_models(args.models or None, package=args.package, fmu_dir=args.fmus, backend=args.backend, force=args.force)
    return 0


def cmd_simulate(args) -> int:
    from .build import ensure_fmu
    from .simulator import Simulator

    fmu = ensure_fmu(args.model, package=args.package, fmu_dir=args.fmus, backend=args.backend)
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


def cmd_demo(args) -> int:
    from .build import build_models
    from .report.figures import plot_step_responses
    from .simulator import Simulator

    print("1/2 building the iGrGen test benches")
    outcomes = build_models(package=args.package, fmu_dir=args.fmus, backend=args.backend)
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


def _result_table(result, labels=None) -> str:
    labels = labels or {}
    lines = [f"method {result.method}: best fitness {result.fun:.6g} after {result.nfev} simulations, "
             f"{result.nit} iterations, {result.wall_time:.1f} s ({result.n_failed} failed)",
             f"stop: {result.stop_reason}", "", f"  {'parameter':24s} {'estimate':>12s}"]
    post = result.posterior
    if post is not None:
        lines[-1] += f"  {'posterior mean':>14s}  {int(round(100 * post.level))} % credible interval"
    for k, name in enumerate(result.names):
        row = f"  {labels.get(name, name):24s} {result.x[k]:12.6g}"
        if post is not None:
            row += f"  {post.mean[k]:14.6g}  [{post.interval[k, 0]:.6g}, {post.interval[k, 1]:.6g}]"
        lines.append(row)
    return "\n".join(lines)


def _run_options(args, estimator_options):
    from .archive.runs import RunOptions

    return RunOptions(method=args.method, seed=args.seed, n_jobs=args.n_jobs, backend=args.joblib_backend,
                      estimator_options=estimator_options)


def cmd_estimate(args) -> int:
    from datetime import datetime

    from .archive.runs import inputs_from_configs, parse_option_overrides, start_run

    inputs = inputs_from_configs(args.configs, package=args.package, fmu_dir=args.fmus, backend=args.backend)
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
    from .archive.runs import resume_run

    result = resume_run(args.archive, n_jobs=args.n_jobs, progress=not args.quiet)
    print(_result_table(result))
    return 0


def cmd_rerun(args) -> int:
    from .archive.runs import rerun

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

    from .archive.runs import summary_json

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
        p.add_argument("--backend", default="auto", choices=["auto", "openmodelica", "embedded"],
                       help="Modelica-to-FMU backend; auto = OpenModelica where omc exists (default %(default)s)")

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

    p = sub.add_parser("demo", help="build the FMUs and plot every test bench's step response")
    p.add_argument("--results", default="results", help="output directory (default %(default)s)")
    model_options(p)
    p.set_defaults(func=cmd_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
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
