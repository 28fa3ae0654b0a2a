"""The validation report of a calibrated unit: one self-contained HTML file (and, printed
from it by headless Chromium, a PDF of the same: :mod:`.pdf`).

Per test, training and held out: the measured and simulated output with the residual,
the metrics of :mod:`.validation` and each one's pass or fail against the tolerance
bands of :mod:`.tolerances`. Per unit: the delivered record in the simulators' formats
with every parameter and where it came from (:mod:`.unit`), the noise model, the
diagnosis when one is given, and the provenance (:mod:`.provenance`). Figures are PNGs
embedded as base64 ``data:`` URIs and the style sheets are inline, so the page opens
offline, can be mailed, and is archived as one file.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Sequence

import numpy as np

from ..version import __version__
from ..calibration import inputs_from_experiments
from ..compiler.source import ModelSource
from ..errors import ConfigError, RapidCosimError
from ..estimators.uncertainty import Uncertainty
from ..experiment import Experiment
from ..experiment.electrical import describe_recording
from ..fitting.engine import EngineSpec
from ..validation.curves import FitCurves, curves_at, metrics
from .archives import ArchivedRun, caption
from .fits import plot_experiment
from .htmlkit import STYLE, e, mark, png
from .provenance import provenance
from .sections import (diagnosis_section, failures_section, metrics_table, noise_section, provenance_section, record_section,
                       recording_section, summary, timebase_section, tolerance_table)
from ..validation.tolerances import Check, Tolerances, judge, verdict
from .unit import DeliveredRecord, DiagnosisSummary, delivered_record, noise_summary
from ..validation.metrics import ValidationMetrics

TRAINING, HELD_OUT = "training", "held out"


@dataclass(frozen=True)
class PageOptions:
    """What the report is told beyond the run: the bands, the held-out tests (predicted
    at the training calibration), a diagnosis, and where the record's machine sits
    (``mva``, its MVA base, for the .dyd record)."""

    tolerances: Tolerances = field(default_factory=Tolerances)
    heldout: tuple[Experiment, ...] = ()
    diagnosis: DiagnosisSummary | None = None
    bus: int = 1
    machine_id: str = "1"
    mva: float | None = None
    source: ModelSource = ModelSource()  # where a held-out test's model is built
    record_note: str = ""  # above the record: whose it is and why (rapid-cosim identify's recommendation)


@dataclass(frozen=True)
class ValidationPage:
    path: Path
    metrics: tuple[ValidationMetrics, ...]
    checks: tuple[tuple[Check, ...], ...]  # per test, in the order of metrics
    n_figures: int
    record: DeliveredRecord
    pdf: Path | None = None  # the same printed by headless Chromium, when asked for

    @property
    def passed(self) -> bool | None:
        """Every test passes every judged metric (None: nothing judged)."""
        verdicts = [verdict(c) for c in self.checks]
        judged = [v for v in verdicts if v is not None]
        return None if not judged else all(judged)


def write_validation_page(run: ArchivedRun, out: str | Path, *, uncertainty: Uncertainty | None = None,
                          interval_note: str = "", options: PageOptions | None = None) -> ValidationPage:
    """``out`` (.html) for the archived ``run``; ``uncertainty`` gives the intervals when
    the run's own method gave none (``interval_note`` says where they come from)."""
    opts = options or PageOptions()
    out = Path(out)
    problem = run.inputs.problem
    x = np.asarray(run.result.x, dtype=float)
    unc = run.result.uncertainty or uncertainty
    curves = [(curves_at(run.inputs, x, i), TRAINING) for i in range(len(problem.experiments))]
    curves += [(c, HELD_OUT) for c in heldout_curves(run, x, opts)]
    rows, figures = [], []
    for c, role in curves:
        m = metrics(c, role)
        checks = judge(m, opts.tolerances)
        rows.append((m, checks))
        figures.append(_figure(c, m, checks))
    record = delivered_record(run, x, unc, bus=opts.bus, machine_id=opts.machine_id, mva=opts.mva)
    experiments = [*problem.experiments, *opts.heldout]
    recorded = [w for w in map(describe_recording, experiments) if w]
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    n_pass = sum(verdict(c) is True for _, c in rows)
    n_fail = sum(verdict(c) is False for _, c in rows)
    note = interval_note if run.result.uncertainty is None else ""
    body = [f"<h1>Validation of the calibrated model: {e(', '.join(x.name for x in experiments))}</h1>",
            f"<p class=note>Archive <code>{e(str(run.path))}</code>; method {e(run.result.method)}, "
            f"best fitness {run.result.fun:.4g} after {run.result.nfev} simulations; "
            f"written {when} by rapid-cosim {__version__}.</p>",
            f"<p id=overall>{n_pass} of {len(rows)} tests pass every judged metric, {n_fail} fail; "
            f"{sum(r == HELD_OUT for _, r in curves)} of the {len(rows)} are held out.</p>",
            summary(rows),
            "<h2>Error metrics against the tolerance bands</h2>", metrics_table(rows),
            "<p class=note>Per test, from the event (<code>[fitness] pre_step_end</code>) to the end of the window or "
            "a staged test's return. Changes are from the pre-event mean; the settled level is the mean of the last "
            "10 % of the span; times are read on a 1 s moving mean (rise: to 90 % of the settled change; peak: only "
            "when the measured response overshoots; settling: staying within 5 % of the change). Simulations "
            "include the profiled transducer offset; held-out tests are predicted at the training calibration "
            "(only their offset profiled). A test passes when every metric judged is within its band.</p>",
            failures_section(rows),
            "<h3>Tolerance bands</h3>", tolerance_table(opts.tolerances),
            "<h2>Delivered record</h2>",
            f"<p id=delivered>{e(opts.record_note)}</p>" if opts.record_note else "",
            record_section(record, note, unc.level if unc is not None else None),
            "<h2>Noise model and diagnosis</h2>", recording_section(recorded),
            timebase_section([(x.name, x.recording.lines()) for x in experiments]),
            noise_section(noise_summary(experiments)),
            diagnosis_section(opts.diagnosis),
            '<section class="figures"><h2>Measured and simulated</h2>', *figures, "</section>",
            "<h2>Provenance</h2>", provenance_section(provenance(run.path, experiments))]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("<!DOCTYPE html>\n<html lang=en>\n<head><meta charset=utf-8>"
                   f"<title>rapid-cosim validation: {e(run.path.name)}</title><style>{STYLE}</style></head>\n"
                   "<body>\n" + "\n".join(body) + "\n</body>\n</html>\n", encoding="utf-8")
    return ValidationPage(out, tuple(m for m, _ in rows), tuple(c for _, c in rows), len(figures), record)


def validation_page(archive: str | Path, out: str | Path | None = None, *, engine: EngineSpec = EngineSpec(),
                    tolerances: str | Path | None = None, heldout: Sequence[str | Path | Experiment] = (),
                    diagnosis: str | Path | None = None, pdf: str | Path | bool | None = None, bus: int = 1,
                    machine_id: str = "1", mva: float | None = None, source: ModelSource = ModelSource(),
                    record_note: str = ""):
    """The unit's validation report (this module's page) for a finished run, at
    ``out`` (default: the archive's name with .html): ``tolerances`` a TOML file with a
    ``[validation]`` table (default bands otherwise), ``heldout`` experiment configs
    predicted at the run's calibration (or experiments already loaded, e.g. on a
    structure's bench), ``diagnosis`` a ``diagnosis.json``, ``pdf`` True (beside the
    page) or a path: the page printed by headless Chromium; ``record_note`` says, above
    the delivered record, whose record it is and why. A method without
    intervals of its own gets the Laplace approximation at the best point, when the noise
    levels are known."""
    from ..experiment import load_experiment
    from ..calibration.staged import hessian_uncertainty
    from .archives import load_run
    from .pdf import chromium, print_pdf
    from ..validation.tolerances import load_tolerances
    from .unit import read_diagnosis

    # everything the user named is checked before anything is computed
    options = PageOptions(tolerances=load_tolerances(tolerances) if tolerances else Tolerances(),
                          heldout=tuple(p if isinstance(p, Experiment) else load_experiment(p) for p in heldout),
                          diagnosis=read_diagnosis(diagnosis) if diagnosis else None, bus=bus,
                          machine_id=machine_id, mva=mva, source=source, record_note=record_note)
    if pdf:
        chromium()
    run = load_run(archive)
    unc, note = None, ""
    if run.result.uncertainty is None:
        try:
            unc = hessian_uncertainty(run.inputs, run.result.x, archive, engine=engine)
            inflation = max(_ar1_inflation(e) for e in run.inputs.experiments)
            unc = unc.scaled(inflation)
            note = (f"Laplace approximation at the best point, its covariance inflated {inflation:.2g}-fold for "
                    "the pre-event noise's correlation (AR(1))")
        except RapidCosimError as e:
            note = f"the run's method gives none, and no Laplace approximation: {e}"
    page = write_validation_page(run, out or Path(archive).with_suffix(".html"), uncertainty=unc,
                                 interval_note=note, options=options)
    if pdf:
        page = replace(page, pdf=print_pdf(page.path, page.path.with_suffix(".pdf") if pdf is True else pdf))
    return page


def _ar1_inflation(exp) -> float:
    from ..data import ar1_inflation, noise_level

    if exp.pre_step_end is None:
        return 1.0
    return max(ar1_inflation(noise_level(exp.data, col, exp.pre_step_end).phi) for col in exp.outputs.values())


def _figure(c: FitCurves, m: ValidationMetrics, checks: tuple[Check, ...]) -> str:
    exp = c.detail.experiment
    fig = plot_experiment(exp, c, title=f"{caption(exp)} ({m.role})")
    return (f'<figure data-test="{e(exp.name)}"><h3>{e(caption(exp))}: {e(m.role)} {mark(verdict(checks))}</h3>'
            f'<img alt="{e(exp.name)}: measured and simulated {e(c.output)}" src="data:image/png;base64,{png(fig)}">'
            f"<figcaption>{e(exp.description)}</figcaption></figure>")


def heldout_curves(run: ArchivedRun, x, opts: PageOptions) -> list[FitCurves]:
    """Each held-out test simulated at the training calibration: its estimated parameters
    take the run's best values by name (a parameter the run did not estimate, or one
    estimated per experiment, cannot be predicted and is refused)."""
    if not opts.heldout:
        return []
    best = dict(zip(run.inputs.problem.names, map(float, x)))
    trained = {e.name for e in run.inputs.experiments}
    for exp in opts.heldout:
        if exp.name in trained:
            raise ConfigError(f"{exp.name} is a training test of {run.path}; a held-out test is one the run "
                              "did not see", str(exp.config_path))
    inputs = inputs_from_experiments(list(opts.heldout), source=opts.source, fmus=run.inputs.fmus)
    names = inputs.problem.names
    missing = [n for n in names if n not in best]
    if missing:
        raise ConfigError(f"held-out test(s) estimate {', '.join(missing)}, which {run.path} did not estimate "
                          f"(it estimated {', '.join(best)}); a held-out test is predicted at the training values",
                          str(opts.heldout[0].config_path), "estimate")
    xh = np.array([best[n] for n in names])
    return [curves_at(inputs, xh, i) for i in range(len(inputs.experiments))]

