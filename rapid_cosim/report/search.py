"""How the searches went, from the archived iterations: convergence (best fitness
against simulations used, PF vs PSO) and the particle clouds of the first stage in the
R-Ts plane."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from matplotlib import cm, colors

from ..archive import RunArchive
from ..estimators.base import Iteration
from .archives import ArchivedRun
from .figures import plt, save
from .fits import COLORS, STYLES

GLOBAL_STAGES = ("pf", "pso", "smc")


def _iterations(run: str | Path | ArchivedRun) -> tuple[list[Iteration], tuple[str, ...], np.ndarray, np.ndarray]:
    """A loaded run already holds the archived iterations: no second read of the file."""
    if isinstance(run, ArchivedRun):
        space = run.inputs.problem.space
        return list(run.result.history), tuple(run.result.names), space.lower, space.upper
    with RunArchive(run) as view:
        return view.iterations(), view.names, view.lower, view.upper


def convergence_curve(iterations: Sequence[Iteration]) -> tuple[np.ndarray, np.ndarray, int]:
    """(simulations used, best fitness so far) after each iteration, and the number of
    iterations of the first stage."""
    n = np.array([it.n_sims for it in iterations])
    f = np.array([it.best_fitness for it in iterations])
    first = iterations[0].stage if iterations else ""
    k = next((i for i, it in enumerate(iterations) if it.stage != first), len(iterations))
    return n, f, k


WITHIN = 0.01  # "converged": best fitness within 1 % of the lowest either method reached


def simulations_to_reach(sims: np.ndarray, best: np.ndarray, target: float) -> int | None:
    """Simulations used when the best fitness first reached ``target`` (None: never)."""
    hit = np.flatnonzero(best <= target)
    return int(sims[hit[0]]) if hit.size else None


def plot_convergence(tests: Mapping[str, Mapping[str, str | Path | ArchivedRun]], out: str | Path, *,
                     ncols: int = 4, dpi: int = 100) -> Path:
    """One panel per test: best fitness (log) against simulations, a line per method;
    a dot marks where the first stage hands over to Nelder-Mead. Runs are archive paths
    or already loaded runs."""
    n = len(tests)
    ncols = min(ncols, n)
    nrows = (n + ncols - 1) // ncols
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, 2.9 * nrows), squeeze=False)
    for ax, (test, archives) in zip(axes.flat, tests.items()):
        curves = {label: convergence_curve(_iterations(run)[0]) for label, run in archives.items()}
        lowest = min(c[1][-1] for c in curves.values())
        for k, (label, (sims, best, k1)) in enumerate(curves.items()):
            color = COLORS.get(label, f"C{k}")
            n1 = simulations_to_reach(sims, best, lowest * (1 + WITHIN))
            reach = f"within {100 * WITHIN:g} % after {n1}" if n1 is not None else f"never within {100 * WITHIN:g} %"
            ax.plot(sims, best, STYLES.get(label, "-"), drawstyle="steps-post", color=color, lw=1.4,
                    label=f"{label}: {sims[-1]} sims, {reach}")
            if 0 < k1 < len(sims):
                ax.plot(sims[k1 - 1], best[k1 - 1], "o", color=color, ms=4)
        ax.set_yscale("log")
        ax.set_title(test, fontsize=9)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=6.5)
        top = min(ax.get_ylim()[1], 30 * lowest)  # the first iterations' far-off points would flatten the end
        ax.set_ylim(lowest / 1.15, top)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("simulations used")
    for ax in axes[:, 0]:
        ax.set_ylabel("best fitness (pu²)")
    fig.suptitle("Best fitness against simulations used (dot: end of the first stage; 'within 1 %': until the best "
                 "fitness is within 1 % of the lower of the two final values)",
                 fontsize=10)
    fig.tight_layout()
    return save(fig, out, dpi=dpi, tight=True)


def plot_particle_clouds(archives: Mapping[str, str | Path | ArchivedRun], out: str | Path, *, title: str = "",
                         x_name: str = "gov.R", y_name: str = "gov.Ts", dpi: int = 100) -> Path:
    """The first stage's particles of each method in the R-Ts plane, coloured by
    iteration; the Nelder-Mead path in black and the final best as a star."""
    n = len(archives)
    fig, axes = plt.subplots(1, n, figsize=(5.2 * n + 0.8, 4.4), squeeze=False, sharey=True)
    axes = axes[0]
    norm = None
    for ax, (label, run) in zip(axes, archives.items()):
        its, names, lower, upper = _iterations(run)
        ix, iy = names.index(x_name), names.index(y_name)
        first = [it for it in its if it.stage in GLOBAL_STAGES]
        rest = [it for it in its if it.stage not in GLOBAL_STAGES]
        n_it = max(len(first), 1)
        norm = colors.Normalize(vmin=1, vmax=max(n_it, 2))
        cmap = plt.get_cmap("viridis")
        for it in first:
            ax.scatter(it.x[:, ix], it.x[:, iy], s=11, color=cmap(norm(it.index + 1)), alpha=0.75, lw=0)
        if rest:
            path_xy = np.array([first[-1].best_x] + [it.best_x for it in rest]) if first else \
                np.array([it.best_x for it in rest])
            ax.plot(path_xy[:, ix], path_xy[:, iy], "-", color="k", lw=0.9, label="Nelder-Mead best")
        final = its[-1].best_x
        ax.plot(final[ix], final[iy], "*", ms=15, mfc="gold", mec="k", mew=0.8,
                label=f"best: R = {final[ix]:.4f}, Ts = {final[iy]:.2f} s")
        if first:
            b = first[-1].best_x
            ax.plot(b[ix], b[iy], "o", ms=14, mfc="none", mec="crimson", mew=1.3, zorder=5,
                    label=f"best after stage 1 ({first[-1].n_sims} sims)")
        ax.set_xlim(lower[ix], upper[ix])
        ax.set_ylim(lower[iy], upper[iy])
        ax.set_xlabel("R (pu)")
        ax.set_title(f"{label}: {len(first)} iterations, {first[0].x.shape[0] if first else 0} particles",
                     fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right", framealpha=0.85)
    axes[0].set_ylabel("Ts (s)")
    if norm is not None:
        sm = cm.ScalarMappable(norm=norm, cmap=plt.get_cmap("viridis"))
        cbar = fig.colorbar(sm, ax=list(axes), fraction=0.03, pad=0.02)
        cbar.set_label("iteration of the first stage")
    if title:
        fig.suptitle(title, fontsize=10)
    return save(fig, out, dpi=dpi, tight=True)
