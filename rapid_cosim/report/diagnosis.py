"""The discrepancy workflow's report, from its record (``diagnosis.json`` and
``diagnosis.h5``) alone: the verdict with its evidence, and the residuals before and
after the named effect was added."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np

from .figures import plt, save
from ..diagnose.catalogue import VerdictKind


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
        sigma = record["noise"]["tests"][test]["sigma"]
        for w in windows.get(test, []):
            if w["systematic"]:
                ax.axvspan(w["start"], w["end"], color="tab:red", alpha=0.08, lw=0)
        ax.axhspan(-2 * sigma, 2 * sigma, color="0.85", alpha=0.6, lw=0, label="recorder noise +-2 sigma")
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
    if VerdictKind.of(record["effect"]) is VerdictKind.AMBIGUOUS:
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
    if VerdictKind.of(record["effect"]) is VerdictKind.AMBIGUOUS:
        text = text.replace("ambiguous", f"ambiguous between {' and '.join(record['candidates'])}")
    lines.append(f"**Verdict: {text}.** {record['reason']}.")
    unexplained = record.get("unexplained")
    if unexplained:
        lines += ["", f"Where the model still misses: {unexplained['where']['summary']}."]
        if unexplained["where"]["flagged"]:
            lines.append(f"Phases above {1.5:g} noise levels: {', '.join(unexplained['where']['flagged'])}.")
    lines += _noise_lines(record) + _adequacy_lines(record) + _search_lines(record) + _profile_lines(record)
    lines += _variant_lines(record)
    for effect, m in (record.get("materiality") or {}).items():
        lines.append(f"\nMateriality of {effect}: fitted at {m['size_share']:.0%} of its material size, removing "
                     f"{m['gap_share']:.0%} of the gap above the noise: {'material' if m['material'] else 'immaterial'}.")
    sep = record.get("separating_test")
    if sep:
        lines += ["", f"Next test: {sep['advice']}."]
    lines += ["", f"Training tests: {', '.join(record['training'])}; held out: {', '.join(record['heldout']) or 'none'}.", "",
              "## Ranking (BIC on residuals whitened by the recorder's noise model; lower is better)", "",
              "| candidate | dBIC | fitness (whitened deviance per sample) | parameters |", "|---|---:|---:|---|"]
    for r in record["ranking"]:
        params = ", ".join(f"{k} = {v:.4g}" for k, v in r["parameters"].items())
        lines.append(f"| {r['label']} | {r['delta']:.1f} | {r['fitness']:.4f} | {params} |")
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
        other = (record.get("exchanged_intervals") or {}).get(name)
        if other:  # the tests fit it either way round with a partner
            iv += f" or [{other[0]:.4g}, {other[1]:.4g}] (exchanged)"
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


def _noise_lines(record: dict) -> list[str]:
    lines = ["", "## The recorder's noise (from the quiet stretches)", ""]
    for k, r in enumerate(record["noise"]["recorders"]):
        pars = ", ".join(f"{n} {v['value']:.3g} (+-{100 * v['relative_se']:.0f} %)" for n, v in r["parameters"].items())
        bics = ", ".join(f"{f} {b - min(r['bic'].values()):+.1f}" for f, b in r["bic"].items())
        lines.append(f"- recorder {k + 1} ({', '.join(r['tests'])}; {r['stretches']} stretches, {r['samples']} samples): "
                     f"**{r['family']}**: {pars}; BIC of the families: {bics}.")
        lines.append(f"  Quiet-data autocorrelation at lags 1-6: {', '.join(f'{a:.2f}' for a in r['acf'][:6])}; "
                     f"the model's: {', '.join(f'{a:.2f}' for a in r['acf_model'][:6])}.")
    timing = record.get("timing") or {}
    if timing:
        worst = max(timing.values(), key=lambda v: v["steepest_second_share"])
        jitter = max(v["jitter_ms"] for v in timing.values())
        lines.append(f"- Time stamps jitter by up to {jitter:.1f} ms (RMS); were the stamps that far off, the response's "
                     f"slope would add {100 * max(v['variance_share'] for v in timing.values()):.2g} % of the noise "
                     f"variance over a test ({100 * worst['steepest_second_share']:.2g} % over its steepest second): "
                     "negligible at the adequacy level." if worst["steepest_second_share"] < 0.05 else
                     f"- Time stamps jitter by up to {jitter:.1f} ms: over the steepest second of a test that could add "
                     f"{100 * worst['steepest_second_share']:.0f} % of the noise variance; the adequacy does not model it.")
    return lines


def _adequacy_lines(record: dict) -> list[str]:
    adequacy = record.get("adequacy")
    if not adequacy:
        return []
    after, before = adequacy["after"], adequacy["before"]
    lines = ["", f"## Adequacy (p-values against the null computed for each test: {after['replicates']} bootstrap "
                 f"replicates of the recorder's noise; Holm over the tests, family-wise level {after['alpha']:g})", "",
             "| test | variance ratio before | p before | variance ratio after | Ljung-Box Q after | p after (Holm) "
             "| adequate |", "|---|---:|---:|---:|---:|---:|---|"]
    for test, a in after["tests"].items():
        b = before["tests"][test]
        lines.append(f"| {test} | {b['variance_ratio']:.3f} | {b['p_holm']:.2g} | {a['variance_ratio']:.3f} | "
                     f"{a['ljung_box_q']:.1f} | {a['p']:.2g} ({a['p_holm']:.2g}) | {'yes' if a['adequate'] else 'no'} |")
    lines.append(f"| campaign | {before['pooled_variance_ratio']:.3f} | {before['p']:.2g} | "
                 f"{after['pooled_variance_ratio']:.3f} | | {after['p']:.2g} | {'yes' if after['adequate'] else 'no'} |")
    return lines


def _search_lines(record: dict) -> list[str]:
    search = record.get("search") or {}
    rows = search.get("candidates") or {}
    if not rows:
        return []
    lines = ["", f"## Search (multistart least squares: starts that reached each candidate's best within "
                 f"{search['margin_bic']:g} in BIC; fewer than {search['min_reached']} leaves it uncertain)", "",
             "| candidate | starts | reached the best | next basin (dBIC) |", "|---|---:|---:|---:|"]
    for label, r in rows.items():
        others = [d for d in r["waterfall_dbic"] if d > search["margin_bic"]]
        lines.append(f"| {label} | {r['starts']} | {r['reached']} | {f'{min(others):.1f}' if others else '-'} |")
    if search.get("uncertain"):
        lines.append(f"\n**{search['warning']}.**")
    return lines


def _profile_lines(record: dict) -> list[str]:
    profiles = record.get("profiles") or {}
    if not profiles:
        return []
    lines = ["", "## Profile likelihoods of the effect's parameters", ""]
    for name, p in profiles.items():
        lo, hi = p["interval_90"]
        lines.append(f"- {name}: optimum {p['optimum']:.4g}, 90 % likelihood-ratio interval [{lo:.4g}, {hi:.4g}]; "
                     f"{'the search missed a better point' if p.get('better_than_search') else 'no better point elsewhere in its range'}.")
    return lines


def _variant_lines(record: dict) -> list[str]:
    variants = record.get("variants") or {}
    if not variants:
        return []
    lines = ["", f"## Variants of form tried before blaming the documentation ({', '.join(variants['documented'])} "
                 f"freed with the effect in {variants['story']})", ""]
    for label, v in variants["variants"].items():
        lines.append(f"- {label} (documentation kept): {v['delta_bic']:+.1f} in BIC against {variants['story']}.")
    lines.append(f"- Outcome: {variants['outcome']}.")
    return lines
