"""How sure each candidate's optimum is: how many of its multistart's starts reached it.

A candidate whose best was reached by few starts may have a better point that no start
found, or the tests may not decide between its basins; where that candidate is the
winner or a close rival, the verdict says so (:class:`~.result.SearchCertainty`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Mapping, Sequence

import numpy as np

from .candidates import CandidateFit
from .result import CandidateSearch, NextBasin, SearchCertainty
from .selection import Ranked, Verdict

MIN_REACHED = 3  # starts that must end at a candidate's best for its optimum to count as certified
REACHED_MARGIN_BIC = 2.0


def search_certainty(fits: Mapping[str, CandidateFit], verdict: Verdict, ranked: Sequence[Ranked],
                     threshold: float) -> SearchCertainty:
    """The starts that reached each candidate's best (within :data:`REACHED_MARGIN_BIC`),
    and a warning when the winner or a close rival (within ``threshold`` of it) was
    reached by fewer than :data:`MIN_REACHED`, with its next basin where there is one."""
    rows = {}
    for label, fit in fits.items():
        reached = fit.reached_best(REACHED_MARGIN_BIC)
        if reached is None:
            continue
        f = fit.waterfall[np.isfinite(fit.waterfall)]
        delta = (fit.n_samples * np.log(np.sort(f) / np.min(f))).tolist() if f.size else []
        rows[label] = CandidateSearch(int(fit.waterfall.size), reached, delta)
    named = "+".join(verdict.effects) if verdict.effects else verdict.effect
    close = [r.label for r in ranked if r.label == named or r.label in verdict.candidates or r.delta < threshold]
    uncertain = sorted({label for label in close if label in rows and rows[label].reached < MIN_REACHED})
    for label in uncertain:  # with the basin it competes with, as the report shows it
        rows[label] = replace(rows[label], next_basin=_next_basin(fits[label]))
    notes = [_note(label, fits[label], rows[label]) for label in uncertain]
    warning = ("the search is uncertain for " + "; ".join(notes) + ": the tests may not decide between these points, "
               "or a better one may exist") if uncertain else ""
    return SearchCertainty(rows, uncertain, warning, MIN_REACHED, REACHED_MARGIN_BIC)


def _next_basin(fit: CandidateFit) -> NextBasin | None:
    runner_up = fit.next_basin(REACHED_MARGIN_BIC)
    return None if runner_up is None else NextBasin(*runner_up)


def _note(label: str, fit: CandidateFit, r: CandidateSearch) -> str:
    clauses = [f"{label}: its best reached by {r.reached} of {r.starts} starts"]
    if r.next_basin is not None:
        point = r.next_basin.parameters
        moved = [n for n in point if abs(point[n] - fit.parameters[n]) > 0.1 * max(abs(point[n]),
                                                                                  abs(fit.parameters[n]), 1e-12)]
        clauses.append(f"the next basin, {r.next_basin.delta_bic:.1f} worse in BIC, has " + ", ".join(
            f"{n} = {point[n]:.4g} (best {fit.parameters[n]:.4g})" for n in moved or point))
    return "; ".join(clauses)
