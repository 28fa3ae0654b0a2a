"""The structure verdict as Markdown and a figure: the ranking, what the effect catalogue
finds on the winner, each structure's parameters with how well the tests determine them,
the pairs that trade off, and the staged test that would pin down the least determined
parameter."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import plt, save
from ..diagnose.catalogue import VerdictKind


def markdown(record: dict) -> str:
    lines = ["# Which structure fits the unit", "",
             f"**Verdict: {record['structure']}.** {record['reason']}.", "",
             *([f"Next test: {record['separating_test']['advice']}.", ""] if record.get("separating_test") else []),
             "| structure | dBIC | fitness | adequate (variance ratio) | held-out score | parameters |",
             "|---|---:|---:|---|---:|---|"]
    for r in record["ranking"]:
        params = ", ".join(f"{k} = {v:.4g}" for k, v in r["parameters"].items())
        held = "-" if r["heldout_score"] is None else f"{r['heldout_score']:.1f}"
        lines.append(f"| {r['name']} | {r['delta']:.1f} | {r['fitness']:.3e} | "
                     f"{'yes' if r['adequate'] else 'no'} ({r['variance_ratio']:.2f}) | {held} | {params} |")
    if record.get("records"):
        lines += ["", "## The standard records (identify's rules: `rapid-cosim identify` gives the same)", "",
                  f"**Recommended: {record['recommended'] or 'none'}**, {record['recommendation']}.", "",
                  "| record | fit kept | estimated | within the noise (variance ratio) | in words |", "|---|---|---:|---|---|"]
        for r in record["records"]:
            lines.append(f"| {r['model']} | {r['fit']} | {r['n_estimated']} | {'yes' if r['adequate'] else 'no'} "
                         f"({r['variance_ratio']:.2f}) | {r['words']} |")
    eff = record.get("effects")
    if eff:
        lines += ["", f"## What {eff['structure']} misses: the effect catalogue on it", "",
                  f"**{eff['verdict']}** {eff['reason']}.", "",
                  "| candidate | dBIC | parameters |", "|---|---:|---|"]
        for r in eff["ranking"][:6]:
            params = ", ".join(f"{k} = {v:.4g}" for k, v in r["parameters"].items())
            lines.append(f"| {r['label']} | {r['delta']:.1f} | {params} |")
    elif VerdictKind.of(record["structure"]) is VerdictKind.AMBIGUOUS:
        lines += ["", "The effect catalogue was not run: no structure wins."]
    lines += ["", "## Identifiability at each optimum (Fisher information of the prewhitened residuals)", ""]
    for r in record["ranking"]:
        ident = r["identifiability"]
        parts = ", ".join(f"{n}: {v['status']} ({100 * v['relative_se']:.2g} %)" for n, v in ident["parameters"].items())
        lines.append(f"- **{r['name']}** (condition number {ident['condition']:.2g}): {parts}.")
        for t in ident["trade_offs"]:
            lines.append(f"  - {t['a']} and {t['b']} trade off (correlation {t['correlation']:+.2f}).")
        for x in ident.get("exchanges", []):
            lines.append(f"  - {x['a']} and {x['b']} exchange: swapped, the fit changes by {x['change']:+.2g} in the "
                         "sum of squares (two lags in series, no limit between them): which is which is not determined.")
        if r.get("at_bounds"):
            lines.append(f"  - On a bound of its range: {'; '.join(r['at_bounds'])} (widen the range, or the "
                         "structure cannot follow the data there).")
        if r.get("separating_step"):
            lines.append(f"  - Next test: {r['separating_step']['advice']}.")
    return "\n".join(lines) + "\n"


def identifiability_figure(record: dict, out: str | Path, *, dpi: int = 110) -> Path:
    """One panel per structure: the correlation of its estimates, with each parameter's
    relative standard error and status on the axis."""
    ranking = record["ranking"]
    fig, axes = plt.subplots(1, len(ranking), figsize=(3.6 * len(ranking), 3.8), squeeze=False)
    for ax, r in zip(axes[0], ranking):
        ident = r["identifiability"]
        names = list(ident["parameters"])
        corr = np.array(ident["correlation"])
        ax.imshow(corr, vmin=-1, vmax=1, cmap="RdBu_r")
        labels = [f"{n.removeprefix('gov.')}\n{100 * ident['parameters'][n]['relative_se']:.2g} %" for n in names]
        ax.set_xticks(range(len(names)), [n.removeprefix("gov.") for n in names], fontsize=7, rotation=45)
        ax.set_yticks(range(len(names)), labels, fontsize=7)
        for i in range(len(names)):
            for j in range(len(names)):
                ax.text(j, i, f"{corr[i, j]:+.2f}", ha="center", va="center", fontsize=6)
        ax.set_title(f"{r['name']} (dBIC {r['delta']:.0f})", fontsize=9)
    fig.suptitle(f"Correlation of the estimates; relative standard errors beside the names "
                 f"(verdict: {record['structure']})", fontsize=9)
    fig.tight_layout()
    return save(fig, out, dpi=dpi, tight=False)
