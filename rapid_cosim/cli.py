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
