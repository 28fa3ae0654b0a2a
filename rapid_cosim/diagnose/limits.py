"""A diagnosis that knows its limits: the verdict after the criterion has chosen, checked
for materiality (:mod:`.materiality`) and adequacy (:mod:`.adequacy`).

An effect that matters little is dropped ("detectable but immaterial"); a final model
that does not fit to the noise turns the verdict into ``unexplained`` (nothing in the
catalogue fits, or the named part removes too little of the gap: :data:`MIN_PARTIAL_SHARE`),
or into ``<effect> + unexplained remainder``. Each function takes the workflow's context
(its fits, noise floors and tests) and returns the amended verdict with its evidence.
"""

from __future__ import annotations

from .adequacy import misfit_locations
from .candidates import CandidateFit, CandidateSpec
from .catalogue import BASE, NONE, UNEXPLAINED, VerdictKind
from .materiality import gap_share, material
from .selection import Verdict


def check_material(ctx, base: CandidateFit, chosen: CandidateFit, verdict: Verdict):
    """Each named effect must matter (:mod:`.materiality`); the first that does not is
    dropped with those named after it, and the verdict says so."""
    report, kept, previous = {}, [], base
    for k, effect in enumerate(chosen.spec.effects):
        step = chosen if k == len(chosen.spec.effects) - 1 else ctx.fits[CandidateSpec(chosen.spec.effects[:k + 1]).label]
        ok, size, share = material(effect, step.parameters, ctx.tests(previous), ctx.tests(step), ctx.noise,
                                   documented=ctx.training[0].fixed)
        report[effect] = {"material": ok, "size_share": size, "gap_share": share}
        if not ok:
            break
        kept.append(effect)
        previous = step
    if len(kept) == len(chosen.spec.effects):
        return chosen, verdict, report
    dropped = chosen.spec.effects[len(kept)]
    note = (f"{dropped} is detectable but immaterial (fitted at {report[dropped]['size_share']:.0%} of its material "
            f"size, removing {report[dropped]['gap_share']:.0%} of the gap above the noise)")
    if not kept:
        return None, Verdict(NONE, reason=f"{verdict.said}; but {note}"), report
    verdict.effects = kept
    verdict.note(note)
    return previous, verdict, report


# A named effect that leaves the model inadequate is "the part found" only if, alone, it
# removes at least MIN_PARTIAL_SHARE of the gap above the noise, or the effects named
# together remove MIN_NAMED_SHARE; less, and it is a partial explanation of an
# unexplained misfit. Measured (make bench-diagnose, 5 seeds): on out-of-catalogue plants
# the first effect named removed 35 to 42 % alone and a greedy second one brought the
# pair to 51-72 %; catalogue effects that left a remainder removed 55 to 85 % alone, and
# a catalogue pair whose first effect removed only 24 % alone removed 89 % together.
MIN_PARTIAL_SHARE = 0.5
MIN_NAMED_SHARE = 0.8


def inadequate(ctx, verdict: Verdict, ranking, before_tests, after_tests, fit_after):
    """The final model does not fit to the noise: ``unexplained`` if no fitted catalogue
    model does either (or the named part removes too little: under :data:`MIN_PARTIAL_SHARE` of the
    gap), else the named part plus an unexplained remainder; with the best partial
    explanation and where the misfit lies."""
    experiments = ctx.training + ctx.heldout
    where = misfit_locations(experiments, after_tests, ctx.noise)
    passing = [label for label, fit in ctx.fits.items() if label != BASE and not fit.spec.held
               and ctx.adequacy(fit).adequate]
    best = next((r for r in ranking if r.label != BASE), None)
    partial = None
    if best is not None:
        share = gap_share(before_tests, ctx.tests(ctx.fits[best.label]), ctx.noise)
        partial = {"candidate": best.label, "gap_share_removed": share}
    info = {"failing_tests": fit_after.failing, "pooled_variance_ratio": fit_after.pooled_variance_ratio,
            "best_partial_explanation": partial, "adequate_candidates": passing, "where": where}
    named_share = gap_share(before_tests, after_tests, ctx.noise) if verdict.effects else 0.0
    first = ctx.fits.get(CandidateSpec(tuple(verdict.effects[:1])).label) if verdict.effects else None
    first_share = gap_share(before_tests, ctx.tests(first), ctx.noise) if first is not None else 0.0
    info["named_gap_share"], info["first_effect_gap_share"] = named_share, first_share
    ambiguous_failing = verdict.kind is VerdictKind.AMBIGUOUS and not set(verdict.candidates) & set(passing)
    if (verdict.kind is VerdictKind.NONE and not passing) or ambiguous_failing or (
            verdict.effects and first_share < MIN_PARTIAL_SHARE and named_share < MIN_NAMED_SHARE):
        what = ("the base model" if not verdict.effects else
                f"the model with {' + '.join(verdict.effects)} (removing {named_share:.0%} of the gap; "
                f"{verdict.effects[0]} alone {first_share:.0%})")
        clauses = [f"{what} does not fit to the noise (variance ratio {fit_after.pooled_variance_ratio:.2f}, "
                   f"tests {', '.join(fit_after.failing) or 'pooled'}) and no catalogue model does"]
        if partial is not None:
            clauses.append(f"the best partial explanation, {partial['candidate']}, removes "
                           f"{partial['gap_share_removed']:.0%} of the gap")
        clauses.append(f"misfit {where['summary']} ({verdict.said})")
        return Verdict(UNEXPLAINED, candidates=list(verdict.candidates), reason="; ".join(clauses)), info
    verdict.note(f"the final model still misses structure (variance ratio "
                       f"{fit_after.pooled_variance_ratio:.2f}; {where['summary']})")
    return verdict, info


def verdict_text(verdict: Verdict, fit_after) -> str:
    named = " + ".join(verdict.effects) if verdict.effects else verdict.effect
    if not fit_after.adequate and verdict.kind is not VerdictKind.UNEXPLAINED:
        return f"{named} + unexplained remainder"
    return named
