"""Text tables of results, as the command line prints them."""

from __future__ import annotations

from typing import Mapping


def result_table(calibration) -> str:
    """A calibration's best point (with its credible interval when the method gives one),
    under a line saying how it was found."""
    c = calibration
    result = c.result
    failed = result.n_failed if result is not None else 0
    wall = f", {result.wall_time:.1f} s" if result is not None and result.wall_time else ""
    lines = [f"method {c.method}: best fitness {c.fun:.6g} after {c.nfev} simulations, {c.nit} iterations"
             f"{wall} ({failed} failed)", f"stop: {c.message}", "", f"  {'parameter':24s} {'estimate':>12s}"]
    post = c.uncertainty
    if post is not None:
        lines[-1] += f"  {'posterior mean':>14s}  {int(round(100 * post.level))} % credible interval"
    for k, name in enumerate(c.names):
        label = c.labels[k] if k < len(c.labels) else name
        row = f"  {label:24s} {c.x[k]:12.6g}"
        if post is not None:
            row += f"  {post.mean[k]:14.6g}  [{post.interval[k, 0]:.6g}, {post.interval[k, 1]:.6g}]"
        lines.append(row)
    return "\n".join(lines)


def summary_text(summary: Mapping) -> str:
    """What ``rapid-cosim show`` prints of an archive's summary (see ``RunArchive.summary``)."""
    lines = [f"{summary['path']}: {summary['method']} (seed {summary['seed']}) on "
             f"{', '.join(summary['experiments'])}, {summary['status']}",
             f"  {summary['n_iterations']} iterations, {summary['nfev']} simulations ({summary['n_failed']} failed)"
             + (f", {summary['wall_time']:.1f} s" if summary.get("wall_time") else "")]
    best = summary.get("best_fitness")
    lines.append(f"  best fitness {best:.6g}" if best is not None else "  best fitness: none yet")
    post = summary.get("posterior")
    for name, value in summary["best"].items():
        line = f"  {name:24s} {value:.6g}" if value is not None else f"  {name:24s} -"
        if post:
            lo, hi = post["interval"][name]
            line += (f"   mean {post['mean'][name]:.6g}, {int(round(100 * post['level']))} % interval "
                     f"[{lo:.6g}, {hi:.6g}]")
        lines.append(line)
    if summary.get("stop_reason"):
        lines.append(f"  stop: {summary['stop_reason']}")
    for name, recording in (summary.get("recordings") or {}).items():
        lines += [f"  {name}: {line}" for line in recording.get("lines", [])]
    if summary.get("damaged"):
        lines.append(f"  shown: what is intact; {len(summary['damaged'])} damaged part(s)")
    return "\n".join(lines)
