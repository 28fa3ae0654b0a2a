"""``rapid-cosim``'s parser: one short sub-parser per command, the option groups that
several commands share (models, engine, campaign, selection) written once."""

from __future__ import annotations

import argparse
from functools import partial

from ..version import __version__
from .docs import cmd_docs, cmd_example
from .commands import (cmd_benches, cmd_build, cmd_check, cmd_demo, cmd_diagnose, cmd_estimate, cmd_export,
                       cmd_figures, cmd_fleet, cmd_identify, cmd_joint, cmd_report, cmd_rerun, cmd_resume, cmd_show,
                       cmd_simulate, cmd_staged_test, cmd_structures, cmd_table1, cmd_verify)

PACKAGE_HELP = "Modelica package folder (default: the iGrGen shipped with rapid-cosim, or $RAPID_COSIM_PACKAGE)"
FMUS_HELP = "folder the FMUs are built into (default: the user's cache, or $RAPID_COSIM_FMUS)"


def build_parser() -> argparse.ArgumentParser:
    """The parser, one group of commands at a time (the option groups they share are below)."""
    parser = argparse.ArgumentParser(prog="rapid-cosim", description="Calibrate Modelica models of power-plant "
                                     "governors against field measurements.")
    parser.add_argument("--version", action="version", version=f"rapid-cosim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    command = partial(_command, sub)
    for group in (_run_commands, _campaign_commands, _unit_commands, _help_commands):
        group(command)
    return parser


def _command(sub, name, func, help, aliases=()):
    """One sub-parser, its command function set as the default."""
    p = sub.add_parser(name, help=help, aliases=list(aliases))
    p.set_defaults(func=func)
    return p


def model_options(p, why: str = ""):
    """--package, --fmus and --compiler: one ModelSource (cli/commands.py, _source)."""
    from ..compiler import COMPILERS

    p.add_argument("--package", help=PACKAGE_HELP + why)
    p.add_argument("--fmus", help=FMUS_HELP)
    p.add_argument("--compiler", default="auto", choices=list(COMPILERS),
                   help="Modelica-to-FMU compiler; auto = OpenModelica where omc exists (default %(default)s)")


def runner_option(p):
    from ..simulator import DEFAULT_RUNNER, RUNNERS

    p.add_argument("--runner", default=DEFAULT_RUNNER, choices=list(RUNNERS),
                   help="simulation runner: the exponential integrator (one model evaluation per sample, CVODE "
                        "where its error estimate asks), CVODE in the compiled batch runner, or the Python "
                        "reference loop (default %(default)s; an archive records it, and rerun/resume use it)")


def engine_options(p, where: str, archived: bool = False):
    """--n-jobs, --joblib-backend and --scheduler: one setting of where the work runs
    (fitting.engine.EngineSpec), its choices written once."""
    from ..fitting.engine import JOBLIB_BACKENDS

    default = "as archived" if archived else "%(default)s"
    p.add_argument("--n-jobs", type=int, default=None if archived else 1,
                   help=f"worker processes (-1: all cores; default {default}; with --joblib-backend dask, 1 or "
                        "-1 split each batch over every worker of the cluster)")
    p.add_argument("--joblib-backend", default=None if archived else "loky", choices=list(JOBLIB_BACKENDS),
                   help=f"{where} (default {default})")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="a running dask scheduler, with --joblib-backend "
                   "dask")


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
    engine_options(p, "where the work goes with --n-jobs > 1: candidates fitted in local processes (loky), or "
                      "their batches on a dask cluster")
    model_options(p)


def _run_commands(command) -> None:
    """The sub-parsers of a run: build, simulate, estimate (and its other names), resume, rerun, show, verify, report."""
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

    p = command("estimate", cmd_estimate, "calibrate parameters against one or more experiments (joint fit; "
                "also called as calibrate)", aliases=["calibrate"])
    p.add_argument("configs", nargs="+", help="experiment config files (config.toml) or their folders")
    p.add_argument("--method", default="pf:10+nm", help="estimator chain, e.g. pf:10+nm, pso:10+nm, smc, gd "
                   "(default %(default)s)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--option", action="append", metavar="METHOD.NAME=VALUE",
                   help="estimator option, e.g. pf.n_particles=100 (repeatable)")
    engine_options(p, "where particles run: local processes (loky), or a dask cluster")
    runner_option(p)
    p.add_argument("--archive", help="HDF5 archive to write (default <results>/run-<time>.h5)")
    p.add_argument("--results", default="results")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    model_options(p)

    for name, func, help in (("resume", cmd_resume, "continue an interrupted run from its archive"),
                             ("rerun", cmd_rerun, "re-run an archived run from the archive alone and compare "
                                                  "bit for bit")):
        p = command(name, func, help)
        p.add_argument("archive")
        engine_options(p, "where particles run (the result does not depend on it)", archived=True)
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
    model_options(p, "; for the held-out tests' benches")


def _campaign_commands(command) -> None:
    """The sub-parsers of the paper's campaign: benches, staged tests, Table 1, figures, the joint fit."""
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
    p.add_argument("--experiments", default="experiments", help="experiments folder (default %(default)s, in the "
                   "current folder: the repository's bundled tests)")
    p.add_argument("--per-test-method", default="pf10+nm",
                   help="whose per-test optima are checked against the joint fit (default %(default)s)")
    p.add_argument("--option", action="append", metavar="smc.NAME=VALUE",
                   help="SMC option instead of the defaults (100 particles, 2 moves per stage), e.g. "
                        "smc.n_particles=200 (repeatable)")
    campaign_options(p)


def _unit_commands(command) -> None:
    """The sub-parsers of a unit and a fleet: diagnose, structures, identify, fleet."""
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
    engine_options(p, "where the work goes with --n-jobs > 1")
    model_options(p)

    p = command("fleet", cmd_fleet, "many units, one grid event: each unit's record on file played back and judged "
                "against the tolerance bands and the recorder's noise, the units whose record fails identified, on a dask cluster; the fleet's "
                "page, table and records (exit status 100 + the number of units that failed with an error, 0 if none; a "
                "record that fails is a row, not an error)")
    p.add_argument("fleet", help="the fleet file (fleet.toml), or its folder")
    p.add_argument("--results", default="results/fleet", help="results folder (default %(default)s); a rerun there "
                   "keeps every unit whose inputs have not changed")
    p.add_argument("--n-jobs", "--workers", dest="n_jobs", type=int, default=2,
                   help="local worker processes, one unit at a time each (default %(default)s; -1: all cores)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="a running dask scheduler instead of local workers")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--pdf", action="store_true", help="each identified unit's report as PDF too (headless Chromium)")
    p.add_argument("--check-only", action="store_true", help="play every record on file back and judge it; identify "
                   "nothing (about 2 s a unit; a unit without a record is a failed row)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    model_options(p)


def _help_commands(command) -> None:
    """The sub-parsers of help and delivery: example, docs, check, export, demo."""
    p = command("example", cmd_example, "copy a shipped example (staged tests, units from grid events, a fleet) into "
                "a folder of yours; no name lists them")
    p.add_argument("name", nargs="?", help="the example (none: the list)")
    p.add_argument("dir", nargs="?", help="the folder to copy it into (default ./NAME)")

    p = command("docs", cmd_docs, "print a page of the documentation as installed: config (every key), benches, "
                "structures, formats, or a guide (calibrate, identify, recordings, ...); no topic lists them")
    p.add_argument("topic", nargs="?", help="the page (none: the list)")
    model_options(p, "; the benches page lists its benches")

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
    p.add_argument("--experiments", default="experiments", help="experiments folder (default %(default)s, in the "
                   "current folder: the repository's bundled tests)")
    campaign_options(p)
