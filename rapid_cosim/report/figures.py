"""Figures people would rather look at than read. Every function writes one file and
returns its path.

Every plotting module of this package takes ``plt`` and :func:`save` from here, so the
headless backend (Agg) is selected before pyplot is first imported, whichever module
is imported first."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after selecting the backend)

from ..simulator import Trajectory  # noqa: E402


def save(fig, out: str | Path, *, dpi: int, tight: bool, pad: float | None = None, close: bool = True) -> Path:
    """Write ``fig`` to ``out`` and close it (reports draw many figures in one process;
    ``close=False`` keeps it for a caller who shows it, as a notebook does).

    ``tight`` crops to what is drawn, ``pad`` inches around it (matplotlib's default if
    None); without it the file keeps the figure's own size, as laid out by the caller."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if not tight:
        fig.savefig(out, dpi=dpi)
    elif pad is None:
        fig.savefig(out, dpi=dpi, bbox_inches="tight")
    else:
        fig.savefig(out, dpi=dpi, bbox_inches="tight", pad_inches=pad)
    if close:
        plt.close(fig)
    return out


def plot_step_responses(responses: Mapping[str, Trajectory], out: str | Path, *, title: str = "",
                        output: str = "pm") -> Path:
    """One axis per test bench, the same staged test on each, so effects compare at a glance."""
    n = len(responses)
    cols = 2
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(11, 2.6 * rows), sharex=True, squeeze=False)
    base = responses.get("StagedTest")
    for ax, (name, traj) in zip(axes.flat, responses.items()):
        if base is not None and name != "StagedTest":
            ax.plot(base.time, base[output], color="0.7", lw=1, label="base model")
        ax.plot(traj.time, traj[output], lw=1.5, label=name)
        ax.set_title(name, fontsize=9)
        ax.set_ylabel(f"{output} (pu)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return save(fig, out, dpi=110, tight=False)
