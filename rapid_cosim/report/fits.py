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

from .archives import ArchivedRun, FitCurves, caption, curves_at, fit_curves, load_run
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
    col = exp.outputs[first.output]
    ax.scatter(data.time, data.columns[col], s=dot_size, color="0.6", alpha=0.45, lw=0, label="measured pm",
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
    fig, (ax, ax_res) = plt.subplots(2, 1, figsize=(8.5, 5.4), sharex=True,
                                     gridspec_kw={"height_ratios": [3, 1.25], "hspace": 0.06})
    draw_fit(ax, ax_res, runs, curves, title=title)
    return save(fig, out, dpi=dpi, tight=True)


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
    """Every experiment of a run at ``x``: measured outputs and the simulation (its
    profiled offset added) above, residuals beneath; the figure, saved if ``path``."""
    problem = inputs.problem
    x = np.asarray(x, dtype=float)
    n = len(problem.experiments)
    fig = plt.figure(figsize=(8.5, 3.9 * n))
    outer = fig.add_gridspec(n, 1, hspace=0.35)
    values = ", ".join(f"{label} = {v:.4g}" for label, v in zip(labels, x))
    for i, exp in enumerate(problem.experiments):
        inner = outer[i].subgridspec(2, 1, height_ratios=[3, 1.25], hspace=0.05)
        ax, ax_res = fig.add_subplot(inner[0]), None
        ax_res = fig.add_subplot(inner[1], sharex=ax)
        c = curves_at(inputs, x, i)
        data = exp.data
        ax.scatter(data.time, data.columns[exp.outputs[c.output]], s=3, color="0.6", alpha=0.45, lw=0,
                   label=f"measured {c.output}", rasterized=True, zorder=1)
        ax.plot(c.fine.time, c.simulated, color="tab:blue", lw=1.4, label="simulated", zorder=3)
        ax_res.plot(c.detail.fit.time, c.residual * 1e3, color="tab:blue", lw=0.7)
        ax_res.axhline(0.0, color="k", lw=0.6)
        ax.set_ylabel(c.output)
        ax_res.set_ylabel("residual\n(10⁻³)")
        ax.set_title(f"{caption(exp)}" + (f"; {values}" if i == 0 else ""), fontsize=9)
        ax.legend(fontsize=7.5, loc="best", markerscale=3)
        ax.tick_params(labelbottom=False)
        for a in (ax, ax_res):
            a.grid(alpha=0.3)
    ax_res.set_xlabel("time (s)")
    if title:
        fig.suptitle(title, fontsize=11)
    if path is not None:
        save(fig, path, dpi=dpi, tight=True, close=False)
    return fig
