"""Fit figures of the staged tests, the counterparts of the paper's Figs. 3-8: measured
pm against the calibrated simulations of both chains, residuals beneath.

The curves come from simulating each archive's best point with the archived FMU and
data (see :mod:`.archives`); the simulation is drawn with its profiled transducer
offset added so that it overlays the recording.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, NamedTuple, Sequence

import numpy as np

from ..validation.curves import FitCurves, curves_at
from .archives import ArchivedRun, caption, fit_curves, load_run
from .figures import plt, save

COLORS = {"PSO10+NM": "tab:blue", "PF10+NM": "tab:red"}
STYLES = {"PSO10+NM": "-", "PF10+NM": "--"}


def _color(label: str, k: int) -> str:
    return COLORS.get(label, f"C{k}")


def legend_entry(label: str, run: ArchivedRun) -> str:
    return f"{label}: R = {run.value('R'):.4f}, Ts = {run.value('Ts'):.2f} s, fitness {run.result.fun:.3e}"


def draw_fit(ax, ax_res, runs: Mapping[str, ArchivedRun], curves: Mapping[str, FitCurves], *,
             title: str | None = None, legend_size: float = 7.5, dot_size: float = 3.0) -> None:
    """One test on a pair of axes: measurements and simulations above, residuals below."""
    first = next(iter(curves.values()))
    exp = first.detail.experiment
    data = exp.data
    ax.scatter(data.time, exp.measured(first.output)[0], s=dot_size, color="0.6", alpha=0.45, lw=0,
               label=f"measured {first.output}",
               rasterized=True, zorder=1)
    xs = [runs[label].result.x for label in curves]
    same = all(np.allclose(x, xs[0], rtol=1e-3, atol=0) for x in xs)
    for k, (label, c) in enumerate(curves.items()):
        ax.plot(c.fine.time, c.simulated, STYLES.get(label, "-"), color=_color(label, k), lw=1.4,
                label=legend_entry(label, runs[label]), zorder=3)
        ax_res.plot(c.detail.fit.time, c.residual * 1e3, color=_color(label, k), lw=0.7, alpha=0.8,
                    label=label, zorder=2 + k)
    if same and len(curves) > 1:
        ax_res.text(0.995, 0.04, "both methods: same optimum, curves coincide", transform=ax_res.transAxes,
                    ha="right", va="bottom", fontsize=6.5, color="0.3")
    for t_name in ("src.t_step", "src.t_return"):
        t = exp.fixed.get(t_name)
        if t is not None and t < exp.simulation.stop_time:
            for a in (ax, ax_res):
                a.axvline(t, color="0.3", lw=0.6, ls=":", zorder=0)
    ax_res.axhline(0.0, color="k", lw=0.6)
    ax.set_ylabel("pm (pu)")
    ax_res.set_ylabel("residual\n(10⁻³ pu)")
    ax_res.set_xlabel("time (s)")
    ax.grid(alpha=0.3)
    ax_res.grid(alpha=0.3)
    ax.legend(fontsize=legend_size, loc="best", framealpha=0.85, markerscale=3)
    ax.set_title(title if title is not None else caption(exp), fontsize=10)
    ax.tick_params(labelbottom=False)
    ax.set_xlim(data.time[0], data.time[-1])


class Fits(NamedTuple):
    """One staged test, loaded: the runs by method label and their curves. Loading
    simulates, so a caller drawing a test in several figures loads it once."""

    runs: dict[str, ArchivedRun]
    curves: dict[str, FitCurves]


def load_fits(archives: Mapping[str, str | Path]) -> Fits:
    runs = {label: load_run(path) for label, path in archives.items()}
    return Fits(runs, {label: fit_curves(run) for label, run in runs.items()})


def _loaded(test: Mapping[str, str | Path] | Fits) -> Fits:
    return test if isinstance(test, Fits) else load_fits(test)


def plot_test_fit(archives: Mapping[str, str | Path] | Fits, out: str | Path, *, title: str | None = None,
                  dpi: int = 110) -> Path:
    """One staged test: ``archives`` maps a method label to its archive (same test), or is
    that test's :func:`load_fits`."""
    runs, curves = _loaded(archives)
    exp = next(iter(curves.values())).detail.experiment
    if not exp.inputs:
        fig, (ax, ax_res) = plt.subplots(2, 1, figsize=(8.5, 5.4), sharex=True,
                                         gridspec_kw={"height_ratios": [3, 1.25], "hspace": 0.06})
        draw_fit(ax, ax_res, runs, curves, title=title)
        return save(fig, out, dpi=dpi, tight=True)
    fig, (ax_in, ax, ax_res) = plt.subplots(3, 1, figsize=(8.5, 7.2), sharex=True,
                                            gridspec_kw={"height_ratios": [1.7, 3, 1.25], "hspace": 0.08})
    draw_inputs(ax_in, exp)
    draw_fit(ax, ax_res, runs, curves, title="")
    ax_in.set_title(title if title is not None else caption(exp), fontsize=10)
    return save(fig, out, dpi=dpi, tight=True)


def draw_inputs(ax, exp) -> None:
    """The recorded signals that drive the model, as recorded (before conversion)."""
    for k, spec in enumerate(exp.inputs):
        source = exp.files[spec.file] if spec.file is not None else exp.data
        unit = f" ({spec.conversion.unit})" if spec.conversion.unit else ""
        values = np.where(source.valid[spec.column], source.columns[spec.column], np.nan)  # masked: not drawn
        ax.plot(source.time, values, color=f"C{k + 2}", lw=0.8,
                label=f"recorded {spec.column}{unit}, drives {spec.name}")
    ax.set_ylabel(exp.inputs[0].column + (f" ({exp.inputs[0].conversion.unit})" if exp.inputs[0].conversion.unit
                                          else ""))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7.5, loc="best", framealpha=0.85)
    ax.tick_params(labelbottom=False)


def plot_fit_grid(tests: Sequence[Mapping[str, str | Path] | Fits], out: str | Path, *, ncols: int = 2,
                  title: str = "", dpi: int = 100) -> Path:
    """Several tests (archives or :func:`load_fits`, as for :func:`plot_test_fit`), one
    (fit, residual) pair of axes each: Figs. 3-8 on one page."""
    n = len(tests)
    nrows = (n + ncols - 1) // ncols
    fig = plt.figure(figsize=(7.0 * ncols, 4.3 * nrows))
    outer = fig.add_gridspec(nrows, ncols, hspace=0.3, wspace=0.17, top=1 - 0.5 / fig.get_figheight(),
                             bottom=0.04, left=0.06, right=0.98)
    for k, archives in enumerate(tests):
        inner = outer[k // ncols, k % ncols].subgridspec(2, 1, height_ratios=[3, 1.25], hspace=0.05)
        ax = fig.add_subplot(inner[0])
        ax_res = fig.add_subplot(inner[1], sharex=ax)
        runs, curves = _loaded(archives)
        draw_fit(ax, ax_res, runs, curves, legend_size=6.5, dot_size=2.0)
    if title:
        fig.suptitle(title, fontsize=12, y=1 - 0.12 / fig.get_figheight())
    return save(fig, out, dpi=dpi, tight=True, pad=0.15)


def plot_calibration(inputs, x, labels: Sequence[str], *, path: str | Path | None = None, title: str = "",
                     dpi: int = 110):
    """Every experiment of a run at ``x``: recorded inputs (if any), measured outputs and
    the simulation (its profiled offset added), residuals beneath; the figure, saved if
    ``path``."""
    problem = inputs.problem
    x = np.asarray(x, dtype=float)
    n = len(problem.experiments)
    heights = [4.6 if e.inputs else 3.9 for e in problem.experiments]
    fig = plt.figure(figsize=(8.5, sum(heights)))
    outer = fig.add_gridspec(n, 1, hspace=0.35, height_ratios=heights)
    values = ", ".join(f"{label} = {v:.4g}" for label, v in zip(labels, x))
    for i, exp in enumerate(problem.experiments):
        draw_experiment(fig, outer[i], exp, curves_at(inputs, x, i),
                        title=f"{caption(exp)}" + (f"; {values}" if i == 0 else ""))
    if title:
        fig.suptitle(title, fontsize=11)
    if path is not None:
        save(fig, path, dpi=dpi, tight=True, close=False)
    return fig


def plot_experiment(exp, c: FitCurves, *, title: str = "", path: str | Path | None = None, dpi: int = 100):
    """One experiment's curves (:func:`~rapid_cosim.validation.curves.curves_at`) in a figure of its own."""
    fig = plt.figure(figsize=(8.5, 5.6 if exp.inputs else 4.6))
    draw_experiment(fig, fig.add_gridspec(1, 1)[0], exp, c, title=title or caption(exp))
    if path is not None:
        save(fig, path, dpi=dpi, tight=True, close=False)
    return fig


def draw_experiment(fig, cell, exp, c: FitCurves, *, title: str) -> None:
    """Inside one grid cell: recorded inputs (if any), measured and simulated output,
    residuals."""
    ratios = ([1.5] if exp.inputs else []) + [3, 1.25]
    axes = [fig.add_subplot(a) for a in cell.subgridspec(len(ratios), 1, height_ratios=ratios, hspace=0.08)]
    for a in axes[1:]:
        a.sharex(axes[0])
    if exp.inputs:
        draw_inputs(axes[0], exp)
    ax, ax_res = axes[-2], axes[-1]
    ax.scatter(exp.data.time, exp.measured(c.output)[0], s=3, color="0.6", alpha=0.45, lw=0,
               label=f"measured {c.output}", rasterized=True, zorder=1)
    ax.plot(c.fine.time, c.simulated, color="tab:blue", lw=1.4, label="simulated", zorder=3)
    ax_res.plot(c.detail.fit.time, c.residual * 1e3, color="tab:blue", lw=0.7)
    ax_res.axhline(0.0, color="k", lw=0.6)
    ax.set_ylabel(c.output)
    ax_res.set_ylabel("residual\n(10⁻³)")
    ax_res.set_xlabel("time (s)")
    axes[0].set_title(title, fontsize=9)
    ax.legend(fontsize=7.5, loc="best", markerscale=3)
    for a in axes[:-1]:
        a.tick_params(labelbottom=False)
    for a in axes:
        a.grid(alpha=0.3)
