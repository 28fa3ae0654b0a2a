"""Which staged test settles an ambiguity, and how likely is it to, once it is recorded?

Comparing the two rivals' fitted responses on a proposed test (:mod:`.separate`) says
how far apart they are today. The user sees something else: the test recorded with the
recorder's noise, and both rivals refitted on all the tests, the new one included. A
wrong rival refitted to the new test absorbs part of the difference; a noise draw can
hide the rest. So each proposed test is judged by Monte Carlo over that loop:

* the new test is simulated from the rival assumed true, at its fitted parameters, and
  the recorder's fitted noise is added. In the whitened space where the criterion is
  computed that noise is independent standard normal (the noise model's standardised
  innovations), so it is drawn there directly, each test's offset profiled out;
* both rivals are refitted on the old tests and the new one, linearised about their
  present fits: the old tests' whitened residuals and Jacobians (the diagnosis's own)
  and the new test's sensitivities by finite differences. The refit minimises the
  criterion (sum over tests of n log of the mean squared whitened residual) by
  reweighted Gauss-Newton steps, clipped into the bounds, never worse than no step;
* the truth's lead in BIC must clear the decision threshold. The probability is that
  of clearing it, whichever rival is true (the smaller of the two).

Rivals that even the menu's largest test cannot tell apart so (neither leads the other
in half the draws) are one group: the truth need only lead the rivals outside its group,
and the story says that the documentation must decide within it.

The menu: step sizes and signs, how long each step is held before its return, repeats
and a pair of opposite steps, and the dispatch (the data's, or another level within the
documented ``pmin``..``pmax``). The smallest test (step size first, then the time it
takes, then no re-dispatch) reaching ``TARGET`` is proposed.

What the linearisation cannot see: a rival whose refit moves far from its present fit,
into another basin, on the new test. ``make bench-advice`` measures how well the stated
probability holds against the full loop (a new recording, a new diagnosis).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from itertools import product
from typing import Sequence

import numpy as np

from ..fitting.objective import ProblemObjective
from ..simulator import get_simulator
from .candidates import CandidateFit, experiment_blocks
from .result import Advice, AdvisedTest
from .selection import THRESHOLD, NoiseFloor

MAGNITUDES_HZ = (0.05, 0.1, 0.2, 0.4)
HOLDS_S = (25.0, 50.0, 100.0)
PATTERNS = ((-1,), (1,), (-1, -1), (1, 1), (-1, 1), (-1, -1, -1), (1, 1, 1), (-1, 1, -1, 1))
DISPATCH_SHARES = (0.4, 0.6, 0.8)  # of the documented range, besides the data's own dispatch
TARGET = 0.9
DRAWS = 400
FD_STEP = 1e-3  # in unit coordinates, as the diagnosis's Jacobians


@dataclass(frozen=True)
class _Old:
    """A rival's old tests, linearised: whitened residuals and Jacobians in unit coordinates."""

    n: np.ndarray  # samples per test
    rr: np.ndarray  # per test r'r
    Jr: np.ndarray  # (tests, d) J'r
    JJ: np.ndarray  # (tests, d, d) J'J
    u0: np.ndarray  # the fit in unit coordinates
    k: int  # parameters counted by BIC (estimated + one offset per test)


def _linearised(fit: CandidateFit) -> _Old:
    problem = fit.inputs.problem
    space = problem.space
    x = np.array([fit.parameters[n] for n in problem.names])
    u = np.clip(space.to_unit(x), 0.0, 1.0)
    X, steps = space.stepped(u, FD_STEP)
    blocks = ProblemObjective(problem, fit.inputs.fmus).residual_blocks(X)
    n, rr, Jr, JJ = [], [], [], []
    for (exp, _), block in zip(experiment_blocks(problem), blocks):
        r = np.nan_to_num(block[0])
        J = np.nan_to_num((block[1:] - block[0]).T / steps)
        n.append(r.size), rr.append(r @ r), Jr.append(J.T @ r), JJ.append(J.T @ J)
    return _Old(np.array(n, float), np.array(rr), np.array(Jr), np.array(JJ), u,
                fit.n_estimated + len(problem.experiments))


class _Rival:
    """A fitted rival on the menu's tests: its whitened responses and sensitivities."""

    def __init__(self, fit: CandidateFit, template_name: str, noise: NoiseFloor):
        self.fit, self.label = fit, fit.spec.label
        problem = fit.inputs.problem
        self.index = problem.experiment_index(template_name)
        self.old = _linearised(fit)
        self.sim = get_simulator(fit.inputs.fmus[fit.model])
        self.noise = noise
        self.shared = np.array(["@" not in n for n in problem.names])

    def responses(self, test: AdvisedTest, sign: int) -> tuple[np.ndarray, np.ndarray]:
        """Whitened response at the fit (n,) and its sensitivities (n, d) to the unit coordinates."""
        problem = self.fit.inputs.problem
        X, steps = problem.space.stepped(self.old.u0, FD_STEP, self.shared)
        rows = [{**problem.parameters_for(x, self.index), "src.df": sign * test.magnitude_hz,
                 "src.t_step": test.t_step_s, "src.t_return": test.t_step_s + test.hold_s, "gov.p_ref": test.p_ref}
                for x in X]
        names = list(rows[0])
        out = self.sim.simulate_batch(names, np.array([[r[n] for n in names] for r in rows]),
                                      stop_time=test.t_step_s + 2 * test.hold_s, output_interval=self.noise.model.dt,
                                      outputs=["pm"])
        y = self.noise.fit.model.whiten(out.values[:, :, 0])
        g = y[0]
        G = np.where(self.shared, (y[1:] - y[0]).T / np.where(steps == 0, 1.0, steps), 0.0)
        return g, G


def _project(noise: NoiseFloor, n: int):
    """The offset's profile in whitened units: x minus its projection on whitened ones."""
    o = noise.fit.model.whiten(np.ones((1, n)))[0]
    o = o / np.linalg.norm(o)
    return lambda x: x - np.multiply.outer(x @ o, o) if x.ndim > 1 else x - (x @ o) * o


def _refit(old: _Old, blocks: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """The criterion (sum n log s2) after the linearised refit, per draw. ``blocks``: the
    new tests' whitened residuals at the fit (draws, n) with their Jacobians (n, d)."""
    draws = blocks[0][0].shape[0]
    d = old.u0.size
    ee = np.stack([(e * e).sum(1) for e, _ in blocks], 1)  # (draws, tests)
    Ge = np.stack([e @ G for e, G in blocks], 1)  # (draws, tests, d)
    GG = np.stack([G.T @ G for _, G in blocks])  # (tests, d, d)
    nn = np.array([G.shape[0] for _, G in blocks], float)

    def criterion(delta):
        s_old = (old.rr + 2 * delta @ old.Jr.T + np.einsum("ri,tij,rj->rt", delta, old.JJ, delta)) / old.n
        s_new = (ee + 2 * np.einsum("rtd,rd->rt", Ge, delta) + np.einsum("ri,tij,rj->rt", delta, GG, delta)) / nn
        c = (old.n * np.log(np.maximum(s_old, 1e-300))).sum(1) + (nn * np.log(np.maximum(s_new, 1e-300))).sum(1)
        return c, s_old, s_new

    delta = np.zeros((draws, d))
    best, s_old, s_new = criterion(delta)
    for _ in range(4):  # reweighted Gauss-Newton: the criterion's stationary point weighs each test by 1/s2
        A = np.einsum("rt,tij->rij", 1 / s_old, old.JJ) + np.einsum("rt,tij->rij", 1 / s_new, GG)
        g = (1 / s_old) @ old.Jr + np.einsum("rt,rtd->rd", 1 / s_new, Ge)
        A += (1e-9 * np.trace(A, axis1=1, axis2=2)[:, None, None] + 1e-12) * np.eye(d)
        delta = np.clip(old.u0 - np.linalg.solve(A, g[..., None])[..., 0], 0.0, 1.0) - old.u0
        c, s_old, s_new = criterion(delta)
        best = np.minimum(best, c)
    return best


def _menu(template, t_step: float) -> list[AdvisedTest]:
    fixed = template.fixed
    p_ref = float(fixed.get("gov.p_ref", np.nan))
    levels = [(p_ref, False)]
    if "gov.pmin" in fixed and "gov.pmax" in fixed:
        lo, hi = float(fixed["gov.pmin"]), float(fixed["gov.pmax"])
        levels += [(lo + s * (hi - lo), True) for s in DISPATCH_SHARES if abs(lo + s * (hi - lo) - p_ref) > 0.05]
    tests = [AdvisedTest(tuple(sign * m for sign in signs), h, t_step, p, re)
             for m, h, signs, (p, re) in product(MAGNITUDES_HZ, HOLDS_S, PATTERNS, levels)]
    return sorted(tests, key=lambda t: t.size)


@dataclass(frozen=True)
class Settling:
    """A proposed test's chance of settling the choice, each rival assumed true in turn."""

    test: AdvisedTest
    probability: dict[str, float]  # label -> P(it leads every other by the threshold | it is true)
    median_lead: dict[str, float]

    @property
    def worst(self) -> float:
        return min(self.probability.values())


def settling(groups: Sequence[Sequence[_Rival]], test: AdvisedTest, rng: np.random.Generator,
             cache: dict, draws: int = DRAWS, threshold: float = THRESHOLD) -> Settling:
    """Monte Carlo of ``test`` recorded from each group's first rival and every rival
    refitted; the truth must lead every rival outside its group."""
    rivals = [r for g in groups for r in g]
    probability, median = {}, {}
    for group in groups:
        truth = group[0]
        z = {}  # one noise draw per recorded test, shared by all rivals' refits
        criteria = {}
        for rival in rivals:
            blocks = []
            for i, sign in enumerate(test.signs):
                g_t, _ = _cached(cache, truth, test, sign)
                g, G = _cached(cache, rival, test, sign)
                proj = _project(rival.noise, g.size)
                if i not in z:
                    z[i] = rng.standard_normal((draws, g.size))
                blocks.append((proj(g_t - g + z[i]), -proj(G.T).T))
            criteria[rival.label] = _refit(rival.old, blocks)
        log_n = np.log(float(truth.old.n.sum()) + sum(b.shape[1] for b in z.values()))
        bic = {r.label: criteria[r.label] + r.old.k * log_n for r in rivals}
        lead = np.min([bic[r.label] for r in rivals if r not in group], axis=0) - bic[truth.label]
        probability[truth.label] = float(np.mean(lead >= threshold))
        median[truth.label] = float(np.median(lead))
    return Settling(test, probability, median)


def _cached(cache: dict, rival: _Rival, test: AdvisedTest, sign: int):
    key = (id(rival), sign, test.magnitude_hz, test.hold_s, test.p_ref)
    if key not in cache:
        cache[key] = rival.responses(test, sign)
    return cache[key]


def _evidence(cache: dict, a: _Rival, b: _Rival, test: AdvisedTest) -> tuple[float, float]:
    """What ``test`` adds to the BIC difference of ``a`` and ``b`` with their fits held, and
    the RMS of their whitened difference: what the advice said before refits were counted."""
    evidence, n = 0.0, 0
    for sign in test.signs:
        d = _cached(cache, a, test, sign)[0] - _cached(cache, b, test, sign)[0]
        d = _project(a.noise, d.size)(d)
        evidence, n = evidence + float(d @ d), n + d.size
    return evidence, float(np.sqrt(evidence / max(n, 1)))


def _groups(rivals: Sequence[_Rival], largest: AdvisedTest, cache: dict, rng: np.random.Generator,
            threshold: float) -> list[list[_Rival]]:
    """Rivals joined where even the menu's largest test, recorded from either and both
    refitted, lets neither lead the other by the threshold in half the draws: one model on
    every test of the menu (two lags in series on a linear stretch, say), which no staged
    test tells apart."""
    def alike(a: _Rival, b: _Rival) -> bool:
        return max(settling([[a], [b]], largest, rng, cache, draws=SCREEN_DRAWS,
                            threshold=threshold).probability.values()) < SAME

    groups: list[list[_Rival]] = []
    for r in rivals:  # in the verdict's order: each group's first is its best-ranked
        home = next((g for g in groups if any(alike(r, o) for o in g)), None)
        if home is None:
            groups.append([r])
        else:
            home.append(r)
    return groups


SCREEN_DRAWS = 100  # every menu test; those within 0.1 of the target are judged on DRAWS
SAME = 0.5  # rivals that even the largest test settles less often than this are one model to the menu


def advise(fits: Sequence[CandidateFit], template, noise: NoiseFloor, *, seed: int = 0,
           target: float = TARGET, threshold: float = THRESHOLD) -> Advice:
    """The smallest menu test after which the true one of ``fits`` (the rivals an ambiguous
    verdict names, best first) leads every other with probability ``target``, or the
    likeliest, said to fall short."""
    rivals = [_Rival(f, template.name, noise) for f in fits]
    rng = np.random.default_rng(seed)
    cache: dict = {}
    menu_tests = _menu(template, float(template.fixed.get("src.t_step", 10.0)))
    groups = _groups(rivals, max(menu_tests, key=lambda t: (t.magnitude_hz, t.seconds)), cache, rng, threshold)
    menu, chosen, best = [], None, None
    for test in menu_tests if len(groups) > 1 else []:
        s = settling(groups, test, rng, cache, draws=SCREEN_DRAWS, threshold=threshold)
        menu.append(s)
        if s.worst >= target - 0.1:
            s = settling(groups, test, rng, cache, draws=DRAWS, threshold=threshold)
            if s.worst >= target:
                chosen = s
                break
        best = s if best is None or _rank(s) > _rank(best) else best
    if best is not None and chosen is None:
        best = settling(groups, best.test, rng, cache, draws=DRAWS, threshold=threshold)
    return _record(groups, chosen or best, chosen is not None, menu, cache, target, threshold)


def _rank(s: Settling) -> tuple[float, float]:
    """The likeliest test to settle it: the smallest probability over the rivals, then the mean."""
    return s.worst, float(np.mean(list(s.probability.values())))


def _named(group: Sequence[_Rival]) -> str:
    return group[0].label + (f" (or its equal{'s' if len(group) > 2 else ''}, "
                             f"{', '.join(r.label for r in group[1:])})" if len(group) > 1 else "")


def _record(groups, s: Settling | None, found: bool, menu: list[Settling], cache: dict, target: float,
            threshold: float) -> Advice:
    same = [f"{' and '.join(r.label for r in g)} are one model to every test of the menu (even the largest, "
            f"recorded from either and both refitted, lets neither lead by {threshold:g} in half the draws): the "
            "documentation of the unit must decide between them" for g in groups if len(g) > 1]
    menu_words = (f"steps of {1000 * MAGNITUDES_HZ[0]:.0f} to {1000 * MAGNITUDES_HZ[-1]:.0f} mHz held "
                  f"{HOLDS_S[0]:.0f} to {HOLDS_S[-1]:.0f} s, up to {max(map(len, PATTERNS))} of them, at the data's "
                  "dispatch or another within the documented range")
    record = partial(Advice, tuple(r.label for g in groups for r in g), tuple(tuple(r.label for r in g) for g in groups),
                     found=found, target=target, draws=DRAWS, menu=tuple((m.test.describe(), m.worst) for m in menu))
    if s is None:  # one group: nothing to test
        return record(None, 0.0, {}, {}, 0.0, 0.0,
                      words=f"no staged test of the menu ({menu_words}) separates them: " + "; ".join(same))
    t = s.test
    reps = [g[0] for g in groups]
    evidence, rms = min((_evidence(cache, a, b, t) for a in reps for b in reps if a is not b), key=lambda e: e[0])
    chance = (f"recorded with this recorder's noise and every rival refitted on all the tests (linearised about "
              f"today's fits, {DRAWS} simulated recordings), the true one leads every other by {threshold:g} in BIC "
              "or more with probability " + ", ".join(f"{s.probability[g[0].label]:.2f} if {g[0].label} is true"
                                                      for g in groups))
    between = ", ".join(_named(g) for g in groups[:-1]) + f" and {_named(groups[-1])}"
    if found:
        said = (f"{t.describe()} separates {between} with probability {s.worst:.2f}: {chance}. Then: "
                + "; ".join(f"{g[0].label} ahead of every other by {threshold:g} or more names "
                            + " or ".join(r.label for r in g) for g in groups)
                + f"; none ahead happens {1 - s.worst:.0%} of the time or less when one of them is the plant, "
                "and with a remainder on the new test it says that none is")
    else:
        said = (f"no staged test of the menu ({menu_words}) separates {between} with probability {target:g}; the "
                f"best, {t.describe()}: {chance}; the documentation of the unit must decide")
    return record(t, s.worst, s.probability, s.median_lead, evidence, rms, words=". ".join([said, *same]))
