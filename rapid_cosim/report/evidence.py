"""The evidence behind a diagnosis, as pictures: the recorder's noise model against what
the quiet data show, each candidate's multistart waterfall, and the named effect's
profile likelihoods. Made from the diagnosis record alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .diagnosis import load
from .figures import plt, save

MAX_WATERFALLS = 8


def evidence_figure(folder: str | Path, out: str | Path | None = None, *, dpi: int = 110) -> Path:
    record, _ = load(folder)
    out = Path(out or Path(folder) / "evidence.png")
    profiles = record.get("profiles") or {}
    panels = 2 + (1 if profiles else 0)
    fig, axes = plt.subplots(1, panels, figsize=(5.2 * panels, 3.6), squeeze=False)
    _noise_panel(axes[0, 0], record)
    _waterfall_panel(axes[0, 1], record)
    if profiles:
        _profile_panel(axes[0, 2], profiles)
    fig.suptitle(f"Evidence behind the verdict: {record.get('verdict') or record['effect']}", fontsize=10)
    fig.tight_layout()
    return save(fig, out, dpi=dpi, tight=False)


def _noise_panel(ax, record: dict) -> None:
    for k, r in enumerate(record["noise"]["recorders"]):
        lags = np.arange(1, len(r["acf"]) + 1) * r["model"]["dt"]
        colour = f"C{k}"
        ax.plot(lags, r["acf"], "o", color=colour, ms=4, label=f"quiet data, recorder {k + 1}")
        ax.plot(lags, r["acf_model"], "-", color=colour, lw=1.2, label=f"{r['family']} model")
    ax.axhline(0, color="0.6", lw=0.6)
    ax.set_xlabel("lag (s)")
    ax.set_ylabel("autocorrelation")
    ax.set_title("recorder noise: quiet stretches against the model", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)


def _waterfall_panel(ax, record: dict) -> None:
    search = record.get("search") or {}
    rows = search.get("candidates") or {}
    order = [r["label"] for r in record["ranking"] if r["label"] in rows][:MAX_WATERFALLS]
    for k, label in enumerate(order):
        d = np.asarray(rows[label]["waterfall_dbic"])
        ax.plot(np.arange(1, d.size + 1), np.maximum(d, 1e-2), ".-", lw=0.8, ms=3, color=f"C{k % 10}",
                label=f"{label} ({rows[label]['reached']}/{rows[label]['starts']})")
    if order:
        ax.axhline(search["margin_bic"], color="0.3", ls="--", lw=0.8)
        ax.set_yscale("log")
        ax.legend(fontsize=6, ncol=2)
    ax.set_xlabel("start (sorted by final fit)")
    ax.set_ylabel("dBIC to the candidate's best")
    ax.set_title("multistart waterfalls (reached the best / starts)", fontsize=9)
    ax.grid(alpha=0.3)


def _profile_panel(ax, profiles: dict) -> None:
    for k, (name, p) in enumerate(profiles.items()):
        v = np.asarray(p["values"])
        x = v / p["optimum"] if p["optimum"] else v
        ax.plot(x, p["delta_bic"], "o-", ms=3, lw=1, color=f"C{k}", label=name)
    ax.axhline(2.71, color="0.3", ls="--", lw=0.8, label="90 % level")
    ax.set_xscale("log")
    ax.set_yscale("symlog", linthresh=10)
    ax.set_ylim(bottom=-0.5)
    ax.set_xlabel("value / optimum")
    ax.set_ylabel("dBIC (profile)")
    ax.set_title("profile likelihoods of the effect's parameters", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
