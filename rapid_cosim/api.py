"""The Python API: calibrate, resume, rerun, load, diagnose, simulate, export.

Every calibration returns one :class:`Calibration`, in the manner of scipy's
``OptimizeResult`` (``x``, ``fun``, ``nfev``, ``nit``, ``success``, ``message``) plus what
a calibration has beyond an optimisation: named parameters, intervals when the method
gives them, the archive the run lives in, and ``plot()`` / ``to_frame()``. The command
line is a thin layer over these functions.

    import rapid_cosim as rc
    fit = rc.calibrate(["experiments/test1"], method="pf:10+nm", seed=1)
    print(fit)
    fit.plot("test1.png")
"""

from __future__ import annotations

import functools
import tempfile
import warnings
from dataclasses import dataclass, field, replace
from datetime import datetime
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .archive import RunArchive, RunStatus
from .archive.writer import refuse_existing
from .calibration import RunInputs, RunOptions, inputs_from_archive, inputs_from_experiments
from .calibration import rerun as _rerun
from .calibration.runs import Resumed
from .calibration import resume_run, start_run
from .compiler.source import ModelSource
from .errors import ArchiveError, ConfigError, ParameterError, RapidCosimError
from .exchange import NoLayout
from .estimators.base import EstimationResult
from .estimators.uncertainty import Uncertainty
from .experiment import Experiment, load_experiment
from .fitting.engine import EngineSpec, pinned_threads
from .simulator import DEFAULT_RUNNER, BatchResult, Trajectory, get_simulator


def pinned(func):
    """The API function run with one BLAS and OpenMP thread (:func:`~rapid_cosim.fitting.engine.pinned_threads`),
    its ``source=`` checked first (:meth:`~rapid_cosim.compiler.source.ModelSource.check`)."""
    @functools.wraps(func)
    def run(*args, **kwargs):
        source = kwargs.get("source")
        if isinstance(source, ModelSource):
            source.check()
        with pinned_threads():
            return func(*args, **kwargs)

    return run


DELIVERABLES = ("unit.dyr", "unit.dyd", "report.html", "report.pdf")  # what identify writes into its workdir


@dataclass(frozen=True, eq=False)
class Calibration:
    """The outcome of a calibration.

    ``x`` holds the best parameter values (physical units) in the order of ``names``
    (FMU parameter names; ``"<param>@<experiment>"`` for per-experiment ones), ``labels``
    their short labels; ``fun`` is the best fitness (RSSD, or ARSSD over experiments).
    ``uncertainty`` is the posterior of a Bayesian method (``smc``), else None.
    ``identical`` is set by :func:`rerun` only: whether the re-run matched the archive bit
    for bit.
    """

    x: np.ndarray
    fun: float
    nfev: int
    nit: int
    success: bool
    message: str
    method: str
    names: tuple[str, ...]
    labels: tuple[str, ...]
    status: RunStatus
    archive: Path | None
    uncertainty: Uncertainty | None = None
    identical: bool | None = None
    result: EstimationResult | None = field(default=None, repr=False)
    inputs: RunInputs | None = field(default=None, repr=False)

    @property
    def finished(self) -> bool:
        """Whether the run it holds ran to its end (a rerun of an unfinished archive, or a
        partial load, did not)."""
        return self.status is RunStatus.FINISHED

    @property
    def parameters(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, self.x)}

    @property
    def intervals(self) -> dict[str, tuple[float, float]] | None:
        """Credible intervals at ``uncertainty.level``, when the method gives them."""
        return None if self.uncertainty is None else self.uncertainty.intervals()

    def to_frame(self):
        """One row per parameter: name, label, estimate, interval (if any) and the bounds
        searched. Needs pandas."""
        try:
            import pandas as pd
        except ImportError:  # pandas is optional for the package
            raise ImportError("to_frame() needs pandas: pip install pandas") from None
        space = self.inputs.problem.space if self.inputs is not None else None
        rows = []
        for k, (name, label) in enumerate(zip(self.names, self.labels)):
            row = {"parameter": name, "label": label, "estimate": float(self.x[k])}
            if self.uncertainty is not None:
                row.update(mean=float(self.uncertainty.mean[k]), lower=float(self.uncertainty.interval[k, 0]),
                           upper=float(self.uncertainty.interval[k, 1]))
            if space is not None:
                row.update(min=float(space.lower[k]), max=float(space.upper[k]))
            rows.append(row)
        return pd.DataFrame(rows).set_index("parameter")

    def plot(self, path: str | Path | None = None, *, title: str | None = None):
        """Measured and simulated outputs of every experiment at ``x``, residuals beneath.
        Returns the matplotlib figure; also saves it when ``path`` is given."""
        from .report.fits import plot_calibration

        if self.inputs is None:
            raise RapidCosimError("this calibration has no inputs to simulate: load it from its archive "
                                  "(rc.load(path)) to plot it")
        return plot_calibration(self.inputs, self.x, self.labels, path=path,
                                title=title or f"{self.method}: fitness {self.fun:.4g}")

    def __str__(self) -> str:
        from .report.tables import result_table

        return result_table(self)


def _calibration(result: EstimationResult, inputs: RunInputs, archive: Path | None, status: RunStatus,
                 identical: bool | None = None) -> Calibration:
    ok = status is RunStatus.FINISHED and result.n_failed < result.nfev
    return Calibration(x=np.asarray(result.x, dtype=float), fun=float(result.fun), nfev=result.nfev,
                       nit=result.nit, success=ok, message=result.stop_reason, method=result.method,
                       names=tuple(result.names), labels=tuple(inputs.problem.labels), status=status,
                       archive=archive, uncertainty=result.uncertainty, identical=identical, result=result,
                       inputs=inputs)


def as_experiments(experiments: Sequence[str | Path | Experiment] | str | Path | Experiment) -> list[Experiment]:
    """Experiments from configs (files or their folders) or :class:`Experiment` objects."""
    if isinstance(experiments, (str, Path, Experiment)):
        experiments = [experiments]
    out = [e if isinstance(e, Experiment) else load_experiment(e) for e in experiments]
    if not out:
        raise ConfigError("give at least one experiment")
    return out


def example(name: str, dest: str | Path | None = None) -> Path:
    """A shipped example (``rapid_cosim.examples.EXAMPLES``) copied into ``dest`` (default
    ``./NAME``), or left as it is where that folder already holds files; its folder."""
    from .examples import copy_example

    return copy_example(name, dest)[0]


def default_archive(folder: str | Path | None = None) -> Path:
    """``<folder>/run-<time>.h5``; without a folder, a fresh temporary one."""
    folder = Path(folder) if folder is not None else Path(tempfile.mkdtemp(prefix="rapid_cosim_run_"))
    return folder / f"run-{datetime.now():%Y%m%d-%H%M%S-%f}.h5"


def calibrate(experiments: Sequence[str | Path | Experiment] | str | Path | Experiment, method: str = "pf:10+nm",
              *, seed: int = 1, engine: EngineSpec = EngineSpec(), archive: str | Path | None = None,
              options: Mapping[str, Mapping[str, object]] | None = None, runner: str = DEFAULT_RUNNER,
              progress: bool = False, source: ModelSource = ModelSource()) -> Calibration:
    """Estimate the experiments' ``[estimate]`` parameters jointly with ``method`` (a chain
    such as ``"pf:10+nm"``, ``"pso:10+nm"``, ``"smc"``). Every iteration is archived in
    ``archive`` (default: a new file in a temporary folder, named by the result), so the
    run can be resumed, re-run or loaded later. ``options`` overrides estimator options,
    ``{"pf": {"n_particles": 100}}``. ``engine`` says where the simulations run
    (``EngineSpec(n_jobs=2)``: two local processes; ``EngineSpec(backend="dask",
    scheduler=...)``: a dask cluster); ``source`` where the models come from (the
    package, its FMU folder, the compiler)."""
    run_options = RunOptions(method=method, seed=seed, engine=engine, runner=runner,
                             estimator_options={m: dict(o) for m, o in (options or {}).items()})
    return calibrate_with(experiments, run_options.check(), archive=archive, progress=progress,
                          source=source)  # calibrate_with pins the threads


@pinned
def calibrate_with(experiments: Sequence[str | Path | Experiment] | str | Path | Experiment, run_options: RunOptions,
                   *, archive: str | Path | None = None, progress: bool = False,
                   source: ModelSource = ModelSource()) -> Calibration:
    """:func:`calibrate` with its options already built and checked (the CLI checks them
    once, before it reads a recording or announces a run)."""
    path = Path(archive) if archive is not None else default_archive()
    refuse_existing(path)  # before any recording is read
    inputs = inputs_from_experiments(as_experiments(experiments), source=source)
    result = start_run(inputs, run_options, path, progress=progress)
    return _calibration(result, inputs, path, RunStatus.FINISHED)


@pinned
def resume(path: str | Path, *, engine: Resumed = None, progress: bool = False) -> Calibration:
    """Continue an interrupted run from its archive, on the archived engine or on
    ``engine`` (or a function of the archived one); the result is the uninterrupted one."""
    result = resume_run(path, engine=engine, progress=progress)
    return _calibration(result, _inputs(path), Path(path), RunStatus.FINISHED)


@pinned
def rerun(path: str | Path, *, engine: Resumed = None, progress: bool = False) -> Calibration:
    """Execute an archived run again from the archive alone and compare it bit for bit
    (``identical``; ``message`` names the first difference when there is one), on the
    archived engine or on ``engine``."""
    report = _rerun(path, engine=engine, progress=progress)
    calib = _calibration(report.result, _inputs(path), Path(path), RunStatus.FINISHED if report.finished else RunStatus.UNFINISHED,
                         identical=report.identical)
    if not report.identical:
        calib = replace(calib, message=f"different from the archive: {report.first_difference}")
    elif not report.finished:
        calib = replace(calib, message=f"{calib.message} (the archive's run was unfinished: its "
                                       f"{report.iterations_compared} iterations match; resume finishes it)")
    return calib


def load(path: str | Path) -> Calibration:
    """An archived run as a :class:`Calibration`: its result if finished, else the best
    point of its complete iterations (``status`` says which)."""
    path = Path(path)
    if not path.exists():
        raise ArchiveError(f"{path}: no such archive")
    with RunArchive(path) as view:
        inputs = inputs_from_archive(view)
        result = view.result()
        status = view.status
        if result is None:
            result = _partial_result(view)
    return _calibration(result, inputs, path, status)


def _inputs(path) -> RunInputs:
    with RunArchive(path) as view:
        return inputs_from_archive(view)


def _partial_result(view: RunArchive) -> EstimationResult:
    its = view.iterations()
    if not its:
        x, fun, nfev = np.full(len(view.names), np.nan), np.nan, 0
    else:
        best = min(its, key=lambda it: (not np.isfinite(it.best_fitness), it.best_fitness))
        x, fun, nfev = best.best_x, best.best_fitness, its[-1].n_sims
    return EstimationResult(view.method, view.names, x, float(fun), int(nfev), len(its), 0.0,
                            f"{view.status}: {len(its)} complete iterations", tuple(its),
                            int(view.evaluations().failed.sum()))


def diagnose(training: Sequence[str | Path | Experiment], *, heldout: Sequence[str | Path | Experiment] = (),
             workdir: str | Path | None = None, seed: int = 1, engine: EngineSpec = EngineSpec(),
             write_model: bool = False, source: ModelSource = ModelSource(), log=print, **options):
    """Find what the base model misses on the ``training`` experiments (confirmed on the
    ``heldout`` ones): see :mod:`rapid_cosim.diagnose`. Returns its
    :class:`~rapid_cosim.diagnose.workflow.Diagnosis`; ``options`` are those of
    :class:`~rapid_cosim.diagnose.workflow.DiagnoseOptions`."""
    from .diagnose.workflow import DiagnoseOptions

    return diagnose_with(training, DiagnoseOptions(seed=seed, engine=engine, write_model=write_model, **options),
                         heldout=heldout, workdir=workdir, source=source, log=log)  # pinned there


@pinned
def diagnose_with(training: Sequence[str | Path | Experiment], options, *,
                  heldout: Sequence[str | Path | Experiment] = (), workdir: str | Path | None = None,
                  source: ModelSource = ModelSource(), log=print):
    """:func:`diagnose` with its :class:`~rapid_cosim.diagnose.workflow.DiagnoseOptions`
    already built (and so checked: the CLI builds them once, before it reads anything)."""
    from .diagnose.workflow import diagnose as run_diagnosis

    folder = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix="rapid_cosim_diagnose_"))
    return run_diagnosis(as_experiments(training), as_experiments(heldout) if heldout else [], workdir=folder,
                         options=options, source=source, log=log)


@pinned
def identify(unit: str | Path, *, workdir: str | Path | None = None, seed: int = 1,
             engine: EngineSpec = EngineSpec(), source: ModelSource = ModelSource(), mva: float | None = None,
             report: bool = True, pdf: bool = True, log=print):
    """One identification of the unit described by ``unit`` (a ``unit.toml`` or its
    folder, see :mod:`rapid_cosim.identify.unit`): the explanation, every standard
    record's calibration and fidelity, the recommended record written into ``workdir``
    as PSS/E ``unit.dyr`` and, where the MVA base is known (``mva``, else ``[unit] mva``),
    PSLF ``unit.dyd``, and its validation report ``report.html`` and ``report.pdf``, as
    ``rapid-cosim report`` writes it (``report=False``: none; ``pdf=False``: HTML only;
    without Chromium the PDF is left out with the reason). Returns the
    :class:`~rapid_cosim.identify.Identification`, the files in ``files`` and why any
    was not written in ``notes``."""
    from .identify import Unit, identify as run_identification
    from .identify.deliver import NO_DYD, layout_note, record_note
    from .identify.unit import check_mva
    from .report.html import validation_page
    from .report.pdf import print_pdf, unavailable

    spec = Unit.load(unit)
    if mva is not None:  # checked before minutes of work
        spec = replace(spec, mva=check_mva(mva, given=" (--mva, or mva= of rc.identify)"))
    no_pdf = "not asked for (--no-pdf)" if not pdf else unavailable() if report else None
    if report and no_pdf and pdf:
        log(f"the report will be HTML only: {no_pdf}")
    folder = Path(workdir) if workdir is not None else Path(tempfile.mkdtemp(prefix="rapid_cosim_identify_"))
    result = run_identification(spec, workdir=folder, seed=seed, engine=engine, source=source, log=log)
    for path in DELIVERABLES:  # an earlier run's file must not pass for this run's (kept if this one fails)
        (folder / path).unlink(missing_ok=True)
    if result.recommended is None:
        result.notes.update({kind: f"no record recommended: {result.reason}" for kind in ("dyr", "dyd", "report")})
        return result
    record = result.record(result.recommended)
    for kind in ("dyr", "dyd") if spec.mva is not None else ("dyr",):  # a .dyd states the MVA base
        try:
            written = export(record.archive, folder / f"unit.{kind}", bus=spec.bus, machine_id=spec.machine_id,
                             mva=spec.mva)  # refused unless it reproduces its fit (calibration.delivery)
        except NoLayout as e:  # a PSLF .dyd of a record with a deadband: the .dyr carries it
            result.notes[kind] = str(e)
            continue
        result.files[kind] = str(written.path)
        result.reproduced[kind] = written.reproduction.worst
        if kind == "dyr" and written.model != record.model:  # a layout of its own (TGOV1D): what the plain one loses
            result.layout_note = layout_note(record.archive, written.model, written.reproduction.record)
    if spec.mva is None:
        result.notes["dyd"] = NO_DYD
    if not report:
        result.notes["report"] = "not asked for (--no-report)"
        return result
    log(f"the validation report of {record.fit} ...")
    page = validation_page(record.archive, folder / "report.html", engine=engine.local(), heldout=result.heldout_configs,
                           diagnosis=result.diagnosis, bus=spec.bus, machine_id=spec.machine_id, mva=spec.mva,
                           source=source, record_note=record_note(result))
    result.files["report"] = str(page.path)
    if no_pdf:
        result.notes["pdf"] = no_pdf
        return result
    try:
        result.files["pdf"] = str(print_pdf(page.path, folder / "report.pdf"))
    except RapidCosimError as e:  # Chromium there but failing: the HTML page stands
        result.notes["pdf"] = str(e)
    return result


def simulate(model: str | Path, parameters: Mapping[str, float] | Sequence[Mapping[str, float]] | None = None, *,
             stop_time: float | None = None, output_interval: float | None = None, output_times=None,
             outputs: Sequence[str] | None = None, input_time=None, inputs: Mapping[str, np.ndarray] | None = None,
             runner: str = DEFAULT_RUNNER, timeout: float | None = None, source: ModelSource = ModelSource(),
             communication_step: float | None = None) -> Trajectory | BatchResult:
    """Simulate a model of the package (a class name, built if needed) or any FMI 2.0 or
    3.0 FMU, Model Exchange or Co-Simulation (a path ending in ``.fmu``).

    ``parameters`` is one set (names to numbers): a :class:`Trajectory` is returned, and
    a failure raises. Or a batch: a sequence of such mappings, or a mapping of names to
    equal-length arrays; the batch runs in one call of the runner and returns a
    :class:`BatchResult` whose ``values`` are (sets x times x outputs), a failed set
    carrying its status and message instead of raising. The FMU is loaded once per
    process (and again only when its file changes), so repeated calls cost a simulation.

    A model that asks to terminate (FMI terminateSimulation) before ``stop_time`` gives
    the trajectory up to then, with a warning. ``communication_step`` (s) bounds a
    Co-Simulation FMU's communication step, or sets it where the FMU needs a fixed one.
    """
    if not isinstance(model, (str, Path)):
        hint = (": an experiment is simulated through its model, e.g. rc.simulate(exp.model, {**exp.fixed, ...}, "
                "input_time=..., inputs=...)" if isinstance(model, Experiment) else "")
        raise ParameterError(f"model must be a class name of the package or a path to an .fmu; got "
                             f"{type(model).__name__}{hint}")
    fmu = source.fmu(str(model))
    sim = get_simulator(fmu, timeout=timeout)
    grid = dict(stop_time=stop_time, output_interval=output_interval, output_times=output_times, outputs=outputs,
                input_time=input_time, inputs=inputs, runner=runner, communication_step=communication_step)
    batch = _as_batch(parameters)
    if batch is None:
        return sim.simulate(parameters, **grid)
    names, values = batch
    return sim.simulate_batch(names, values, **grid)


def _as_batch(parameters) -> tuple[list[str], np.ndarray] | None:
    """(names, sets x names) when ``parameters`` is a batch, None for one set."""
    if parameters is None:
        return None
    if isinstance(parameters, Mapping):
        arrays = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in parameters.items()}
        if all(a.ndim == 1 and a.size == 1 and np.ndim(parameters[k]) == 0 for k, a in arrays.items()):
            return None
        sizes = {a.size for a in arrays.values()}
        if len(sizes) != 1:
            raise ParameterError(f"a batch of parameters needs arrays of one length; got {sorted(sizes)}")
        return list(arrays), np.column_stack(list(arrays.values()))
    sets = list(parameters)
    if not sets:
        raise ParameterError("an empty batch of parameter sets")
    names = list(sets[0])
    if any(set(p) != set(names) for p in sets):
        raise ParameterError("every parameter set of a batch must name the same parameters")
    return names, np.array([[float(p[n]) for n in names] for p in sets])


@pinned
def export(archive: str | Path, out: str | Path, *, format: str | None = None, bus: int = 1, machine_id: str = "1",
           mva: float | None = None, bus_name: str = "", kv: float = 0.0):
    """Write the calibration in ``archive`` as the grid simulators' record of its standard
    governor (TGOV1, IEEEG1, GGOV1, HYGOV or GAST, told by the bench's ``gov.*`` parameters;
    a deadband in the D layout, TGOV1D say, which PSLF has no layout for):
    a PSS/E ``.dyr`` or PSLF ``.dyd`` record (``format``, default by ``out``'s suffix) for
    machine ``machine_id`` at ``bus``. The values are the archive's best estimates over
    its fixed values over the bench's defaults; ``mva``, the machine's MVA base, is
    written in a ``.dyd`` record (required there; a ``.dyr`` record has none: PSS/E takes
    MBASE from the ``.raw``). The file is read back and simulated on every test of the
    run first, and written only if it reproduces the fit
    (:mod:`rapid_cosim.calibration.delivery`; else :class:`~rapid_cosim.errors.DeliveryError`).
    Returns the :class:`~rapid_cosim.calibration.delivery.Delivered` record (``model``,
    ``text``, ``path``, ``dropped``, ``reproduction``); the tables are
    :mod:`rapid_cosim.exchange.layouts`, the conversions :mod:`rapid_cosim.exchange.tables`."""
    from .calibration.delivery import deliver_record
    from .calibration.record import finished_run
    from .exchange import FORMATS, ExchangeWarning, format_of, machine_note

    kind = format or format_of(out)
    if kind not in FORMATS:
        raise ParameterError(f"format {kind!r}: use dyr (PSS/E) or dyd (PSLF)")
    if kind == "dyd" and (mva is None or not mva > 0):
        raise ParameterError(f"a .dyd record needs the machine's MVA base (mva > 0), got {mva!r}")
    if not Path(archive).exists():
        raise ArchiveError(f"{archive}: no such archive")
    inputs, parameters, x = finished_run(archive)
    delivered = deliver_record(inputs, parameters, x, out, kind=kind, bus=bus, machine_id=machine_id, mva=mva,
                               bus_name=bus_name, kv=kv, source=str(archive))
    note = machine_note({n: v for n, v in parameters.items() if n.startswith("mach.")}, kind)
    if note:  # an electrical-power event's H (and D): the generator's record, not the governor's
        warnings.warn(note, ExchangeWarning, stacklevel=3)  # the caller's line: past export and pinned
    return delivered
