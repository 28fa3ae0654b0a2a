"""The discrepancy workflow's report, from its record (``diagnosis.json`` and
``diagnosis.h5``) alone: the verdict with its evidence, and the residuals before and
after the named effect was added."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from .figures import plt, save


def load(folder: str | Path) -> tuple[dict, dict[str, dict[str, np.ndarray]]]:
    folder = Path(folder)
    record = json.loads((folder / "diagnosis.json").read_text())
    arrays = {}
    with h5py.File(folder / "diagnosis.h5", "r") as f:
        for test in f:
            arrays[test] = {k: f[test][k][()] for k in f[test]}
    return record, arrays


def residual_figure(folder: str | Path, out: str | Path | None = None, *, dpi: int = 110) -> Path:
    """One panel per test: the base model's residual and the residual with the named
    effect, the noise band (+-2 sigma of the pre-step noise), systematic windows shaded."""
    record, arrays = load(folder)
    out = Path(out or Path(folder) / "residuals.png")
    tests = [t for t in record["gap_before"] if t in arrays]  # training tests, then the held-out ones
    cols = 2 if len(tests) > 3 else 1
    rows = (len(tests) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(7 * cols, 2.3 * rows), squeeze=False, sharex=False)
    windows = {t["name"]: t["windows"] for t in record["features"]["tests"]}
    named = "+".join(record["effects"]) if record["effects"] else None
    for ax, test in zip(axes.flat, tests):
        a = arrays[test]
        sigma = record["noise"][test]["sigma"]
        for w in windows.get(test, []):
            if w["systematic"]:
                ax.axvspan(w["start"], w["end"], color="tab:red", alpha=0.08, lw=0)
        ax.axhspan(-2 * sigma, 2 * sigma, color="0.85", alpha=0.6, lw=0, label="noise +-2 sigma")
        ax.plot(a["time"], a["before"], color="0.45", lw=0.8, label="base model")
        if named:
            ax.plot(a["time"], a["after"], color="tab:blue", lw=0.8, label=f"with {named}")
        gb, ga = record["gap_before"][test], record["gap_after"][test]
        held = " (held out)" if gb.get("held_out") else ""
        title = f"{test}{held}: RMSE {gb['rmse_over_noise']:.2f}x noise"
        if named:
            title += f" -> {ga['rmse_over_noise']:.2f}x"
        adequacy = record.get("adequacy")
        if adequacy:
            ok = [adequacy[k]["tests"][test]["adequate"] for k in ("before", "after")]
            title += f"; adequate: {'yes' if ok[0] else 'no'}" + (f" -> {'yes' if ok[1] else 'no'}" if named else "")
        ax.set_title(title, fontsize=9)
        ax.set_ylabel("residual (pu)")
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(tests):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    axes.flat[0].legend(fontsize=7, loc="upper right")
    verdict = record.get("verdict") or record["effect"]
    if record["effect"] == "ambiguous":
        verdict = verdict.replace("ambiguous", "ambiguous between " + " and ".join(record["candidates"]))
    fig.suptitle(f"Residuals: verdict {verdict} (red: windows not explained by noise)",
                 fontsize=10)
    fig.tight_layout()
    return save(fig, out, dpi=dpi, tight=False)


def _fmt(v, digits=4) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def markdown(folder: str | Path) -> str:
    record, _ = load(folder)
    lines = ["# Discrepancy diagnosis", ""]
    text = record.get("verdict") or (" + ".join(record["effects"]) or record["effect"])
    if record["effect"] == "ambiguous":
        text = text.replace("ambiguous", f"ambiguous between {' and '.join(record['candidates'])}")
    lines.append(f"**Verdict: {text}.** {record['reason']}.")
    unexplained = record.get("unexplained")
    if unexplained:
        lines += ["", f"Where the model still misses: {unexplained['where']['summary']}."]
        if unexplained["where"]["flagged"]:
            lines.append(f"Phases above {1.5:g} noise levels: {', '.join(unexplained['where']['flagged'])}.")
    adequacy = record.get("adequacy")
    if adequacy:
        after, before = adequacy["after"], adequacy["before"]
        lines += ["", f"## Adequacy (does the model fit to the noise? variance ratio <= {after['max_variance_ratio']:g}"
                      f" and Ljung-Box p >= {after['min_ljung_box_p']:g})", "",
                  "| test | variance ratio before | Ljung-Box p before | after | p after | adequate after |",
                  "|---|---:|---:|---:|---:|---|"]
        for test, a in after["tests"].items():
            b = before["tests"][test]
            lines.append(f"| {test} | {b['variance_ratio']:.2f} | {b['ljung_box_p']:.2g} | {a['variance_ratio']:.2f} "
                         f"| {a['ljung_box_p']:.2g} | {'yes' if a['adequate'] else 'no'} |")
        lines.append(f"| pooled | {before['pooled_variance_ratio']:.2f} | | {after['pooled_variance_ratio']:.2f} | "
                     f"| {'yes' if after['adequate'] else 'no'} |")
    for effect, m in (record.get("materiality") or {}).items():
        lines.append(f"\nMateriality of {effect}: fitted at {m['size_share']:.0%} of its material size, removing "
                     f"{m['gap_share']:.0%} of the gap above the noise: {'material' if m['material'] else 'immaterial'}.")
    sep = record.get("separating_test")
    if sep:
        lines += ["", f"Next test: {sep['advice']}."]
    lines += ["", f"Training tests: {', '.join(record['training'])}; held out: {', '.join(record['heldout']) or 'none'}.", "",
              "## Ranking (BIC on AR(1)-prewhitened residuals; lower is better)", "",
              "| candidate | dBIC | fitness (ARSSD) | parameters |", "|---|---:|---:|---|"]
    for r in record["ranking"]:
        params = ", ".join(f"{k} = {v:.4g}" for k, v in r["parameters"].items())
        lines.append(f"| {r['label']} | {r['delta']:.1f} | {r['fitness']:.3e} | {params} |")
    if record["second_effect_ranking"]:
        lines += ["", "Second effect (greedy):", "", "| candidate | dBIC |", "|---|---:|"]
        lines += [f"| {r['label']} | {r['delta']:.1f} |" for r in record["second_effect_ranking"]]
    if record["not_excluded"]:
        lines += ["", f"Held at a material size, these fit as well as the base model: {', '.join(record['not_excluded'])}."]
    lines += ["", "## Features of the residuals", "", "| feature | value | points at | reading |", "|---|---:|---|---|"]
    for name, f in record["features"]["summary"].items():
        if isinstance(f, dict) and "points_at" in f:
            lines.append(f"| {name} | {_fmt(f['value'], 3)} | {', '.join(f['points_at'])} | {f['reading']} |")
    lines += ["", "## Parameters", "", "| parameter | before (base) | after | 90 % interval |", "|---|---:|---:|---|"]
    for name, value in record["parameters_after"].items():
        interval = record["parameter_intervals"].get(name)
        iv = f"[{interval[0]:.4g}, {interval[1]:.4g}]" if interval else "-"
        lines.append(f"| {name} | {_fmt(record['parameters_before'].get(name))} | {value:.4g} | {iv} |")
    lines += ["", "## Gap per test (RMSE over the noise level; gap = RMSE above the noise floor)", "",
              "| test | RMSE/noise before | after | gap before (pu) | gap after (pu) |", "|---|---:|---:|---:|---:|"]
    for test, b in record["gap_before"].items():
        a = record["gap_after"][test]
        held = " (held out)" if b.get("held_out") else ""
        lines.append(f"| {test}{held} | {b['rmse_over_noise']:.2f} | {a['rmse_over_noise']:.2f} | "
                     f"{b['gap']:.2e} | {a['gap']:.2e} |")
    if record["model_written"]:
        lines += ["", f"Model written: `{record['model_written']}` ({record['model_file']}), compiled and re-calibrated."]
    return "\n".join(lines) + "\n"
