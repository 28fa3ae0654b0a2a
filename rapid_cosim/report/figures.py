"""Figures people would rather look at than read. Every function writes one file and
returns its path; matplotlib runs headless (Agg)."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after selecting the backend)

from ..simulator import Trajectory  # noqa: E402


def plot_step_responses(responses: Mapping[str, Trajectory], out: str | Path, *, title: str = "",
                        output: str = "pm") -> Path:
    """One axis per test bench, the same staged test on each, so effects compare at a glance."""
    out = Path(out)
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
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
