"""A freed documented constant is named only when no variant of the named effect explains
the same.

A documented constant left free is a flexible thing: a reheat constant T5 off by a third
can round a load controller's withdrawal much as a filter on the controller's power
measurement does, and T4 off by 40 % can round the ends of a ramp much as a rate limit on
the governor's command (rather than on the valve) does. An engineer reads ``doc_T5`` as
"the documentation is wrong", so that reading must win over the variants of form before
it is given:

* each variant of the named effect (:data:`~.catalogue.VARIANTS`) is fitted in its place,
  the documented constant kept as documented;
* a variant that beats the effect-plus-constant by the threshold is named instead, and
  the documentation stands;
* one that comes within the threshold cannot be told apart from it: the verdict is
  ``ambiguous`` between the two stories, with the staged test that separates them, and
  the parameters reported are the simpler story's (the documentation standing);
* only if every variant is worse by the threshold is the constant named.
"""

from __future__ import annotations

from .candidates import CandidateFit, CandidateSpec, default_start
from .catalogue import AMBIGUOUS, EFFECTS, variants_of
from .selection import Verdict, bic


def check_variants(ctx, chosen: CandidateFit, verdict: Verdict, threshold: float):
    """(chosen, verdict, report, simpler): the verdict after the variants of its effect
    have had their chance; ``simpler`` is the variant's fit when the two stories cannot
    be told apart (its parameters are reported), else None."""
    effects = chosen.spec.effects
    documented = [e for e in effects if EFFECTS[e].relative]
    physical = [e for e in effects if not EFFECTS[e].relative]
    parents = [e for e in physical if variants_of(e)]
    if not documented or not parents:
        return chosen, verdict, {}, None
    named_bic = bic(chosen, ctx.noise)
    specs = [CandidateSpec(tuple(variant if e == parent else e for e in physical))
             for parent in parents for variant in variants_of(parent)]
    fits = ctx.fit_many([(spec, default_start(spec, chosen.parameters)) for spec in specs])
    tried = {spec.label: fit for spec, fit in zip(specs, fits)}
    report = {"story": chosen.spec.label, "documented": documented,
              "variants": {label: {"delta_bic": bic(f, ctx.noise) - named_bic, "parameters": f.parameters}
                           for label, f in tried.items()}}
    best_label = min(tried, key=lambda k: report["variants"][k]["delta_bic"])
    best, delta = tried[best_label], report["variants"][best_label]["delta_bic"]
    constants = ", ".join(d.removeprefix("doc_") for d in documented)
    if delta <= -threshold:
        report["outcome"] = "variant"
        verdict = Verdict(best.spec.effects[0], effects=list(best.spec.effects), held_out=verdict.held_out,
                          reason=(f"{verdict.said}; but {best_label} explains it better ({-delta:.1f} in BIC) "
                                  f"with the documented {constants} kept: the documentation stands"))
        return best, verdict, report, None
    if delta < threshold:
        report["outcome"] = AMBIGUOUS
        verdict = Verdict(AMBIGUOUS, candidates=[best_label, chosen.spec.label], held_out=verdict.held_out,
                          reason=(f"{verdict.said}; but {best_label}, with the documented {constants} kept, fits "
                                  f"as well ({delta:+.1f} in BIC): the data cannot tell a documented {constants} "
                                  f"off its value from a {EFFECTS[best.spec.effects[0]].title}; the parameters "
                                  f"given are {best_label}'s, where the documentation stands"))
        return chosen, verdict, report, best
    report["outcome"] = "documented constant"
    verdict.note(f"its variants with the documented {constants} kept fit worse (the best, {best_label}, by "
                       f"{delta:.1f})")
    return chosen, verdict, report, None
