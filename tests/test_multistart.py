"""Multistart least squares: Levenberg-Marquardt in lockstep from a Sobol design, its
waterfall, profiles, and runs of it archived, re-run and resumed like any method."""

from __future__ import annotations

import numpy as np
import pytest

from rapid_cosim.estimators import Evaluations, MSOptions, SearchSpace, multistart, reached_best, run_chain
from rapid_cosim.estimators.profile import grid, profile
from rapid_cosim.estimators.multistart import _Starts
from rapid_cosim.compiler.source import ModelSource


class Residuals:
    """An analytic least-squares objective: ``f(X)`` gives the residual rows."""

    def __init__(self, f):
        self.f, self.calls, self.points = f, 0, []

    def residuals(self, X):
        X = np.atleast_2d(X)
        self.calls += 1
        self.points.append(X.copy())
        R = self.f(X)
        fit = np.sum(R ** 2, axis=1)
        return Evaluations(fit, fit[:, None], np.zeros(len(fit), bool)), R

    def __call__(self, X):
        return self.residuals(X)[0]


def _narrow(X):
    """A broad shallow basin at a = 0.8 and, on the other side, a narrow deep valley at
    a = 0.1 (width 0.01): where a limit acts only over a small part of its range."""
    a, b = X[:, 0], X[:, 1]
    valley = 1.0 - np.exp(-((a - 0.1) / 0.01) ** 2)
    return np.column_stack([0.3 * (a - 0.8), valley * 0.5 + 0.05, b - 0.5])


SPACE = SearchSpace(("a", "b"), np.array([0.0, 0.0]), np.array([1.0, 1.0]))


def test_a_single_local_start_misses_the_narrow_optimum_that_the_design_finds():
    from rapid_cosim.estimators.base import Tracker
    from rapid_cosim.estimators.lm import levenberg_marquardt

    local = levenberg_marquardt(Tracker("lm", Residuals(_narrow), SPACE, np.random.default_rng(0), None),
                                np.array([[0.7, 0.5]]))
    many = multistart(Residuals(_narrow), SPACE, rng=np.random.default_rng(0))
    assert local.u[0, 0] == pytest.approx(0.8, abs=0.02)  # the broad basin
    assert many.x[0] == pytest.approx(0.1, abs=0.005) and many.fun < local.f[0] - 0.1
    fun = many.history[-1].extras["start_fun"]
    # the starts are the best points of a design of 48, so those in the valley lead; the
    # waterfall shows both basins
    assert reached_best(fun, 1e-3) >= 2 and np.max(fun) > 0.3
    assert "screen" in many.history[0].extras and many.history[0].x.shape[0] == 48


def test_without_screening_a_plain_design_may_reach_the_narrow_optimum_once():
    res = multistart(Residuals(_narrow), SPACE, options=MSOptions(screen=0), rng=np.random.default_rng(0))
    fun = res.history[-1].extras["start_fun"]
    assert res.x[0] == pytest.approx(0.1, abs=0.005)
    assert fun.size == 24 and 1 <= reached_best(fun, 1e-4) < 3  # three sets of 8 ran: an uncertain optimum


def test_lm_solves_a_curved_valley_and_respects_the_box():
    rosen = Residuals(lambda X: np.column_stack([10 * (X[:, 1] - X[:, 0] ** 2), 1 - X[:, 0]]))
    space = SearchSpace(("a", "b"), np.array([-2.0, -1.0]), np.array([0.9, 3.0]))  # the optimum (1, 1) is outside
    res = multistart(rosen, space, rng=np.random.default_rng(1))
    assert res.x == pytest.approx([0.9, 0.81], abs=1e-4)
    pts = np.vstack(rosen.points)
    assert np.all(pts >= space.lower) and np.all(pts <= space.upper)


def test_the_same_seed_makes_the_same_calls():
    a, b = Residuals(_narrow), Residuals(_narrow)
    ra = multistart(a, SPACE, rng=np.random.default_rng(5))
    rb = multistart(b, SPACE, rng=np.random.default_rng(5))
    assert a.calls == b.calls and all(np.array_equal(p, q) for p, q in zip(a.points, b.points))
    assert np.array_equal(ra.x, rb.x) and len(ra.history) == len(rb.history)


def test_rounds_cap_the_designs_and_the_waterfall_says_how_sure_the_best_is():
    res = multistart(Residuals(_narrow), SPACE, options=MSOptions(rounds=1, screen=0), rng=np.random.default_rng(0))
    fun = res.history[-1].extras["start_fun"]
    assert fun.size == 8 and reached_best(fun, 1e-4) < 3  # the caller sees an uncertain optimum
    assert "reached the best" in res.stop_reason


def test_a_chain_runs_ms_after_a_global_stage():
    res = run_chain(Residuals(_narrow), SPACE, "pso:3+ms", rng=np.random.default_rng(3))
    assert res.x[0] == pytest.approx(0.1, abs=0.005)


def test_profile_holds_one_parameter_and_refits_the_rest():
    obj = Residuals(_narrow)
    values = grid(SPACE, 0, 11, around=0.1)
    p = profile(obj, SPACE, np.array([0.1, 0.5]), 0, values, rng=np.random.default_rng(0))
    assert np.all(p.x[:, 0] == values)
    assert np.allclose(p.x[:, 1], 0.5, atol=1e-4)  # b refitted to its optimum everywhere
    k = int(np.argmin(p.fitness))
    assert values[k] == pytest.approx(0.1)
    lo, hi = p.interval(n_samples=1000)
    assert 0.05 < lo <= 0.1 <= hi < 0.2  # the narrow valley, not the broad basin


def test_an_objective_without_residual_vectors_is_refused():
    with pytest.raises(ValueError, match="least-squares method needs them"):
        multistart(lambda X: Evaluations.from_fitness(np.sum(X ** 2, axis=1)), SPACE, rng=np.random.default_rng(0))


def test_an_ms_run_is_archived_reruns_identically_and_resumes(fmus, tmp_path):
    """A whitened calibration by multistart least squares through the run machinery."""
    import tomllib

    from conftest import synthetic_config
    from rapid_cosim.calibration import RunOptions, inputs_from_configs, rerun, start_run
    from rapid_cosim.experiment import load_experiment, render_config
    from rapid_cosim.noise import RecorderNoise

    exp = load_experiment(synthetic_config(fmus["StagedTest"], tmp_path / "s", seed=4))
    raw = tomllib.loads(exp.config_text)
    raw["data"]["file"] = str(tmp_path / "s" / "data.csv")
    raw["noise"] = {"pm": RecorderNoise(0.0008, (), float(np.median(np.diff(exp.data.time)))).to_config()}
    (tmp_path / "w").mkdir()
    (tmp_path / "w" / "config.toml").write_text(render_config(raw))
    inputs = inputs_from_configs([tmp_path / "w"], source=ModelSource(fmu_dir=tmp_path.parent / "fmus_ms"))
    options = RunOptions(method="ms", seed=2, estimator_options={"ms": {"n_starts": 4, "rounds": 1}})
    result = start_run(inputs, options, tmp_path / "ms.h5", progress=False)
    assert result.x[0] == pytest.approx(0.06, rel=0.05) and result.x[1] == pytest.approx(4.0, rel=0.15)
    assert 0.7 < result.fun < 1.4  # the whitened deviance per sample of a right model: about one
    assert "start_fun" in result.history[-1].extras
    report = rerun(tmp_path / "ms.h5", progress=False)
    assert report.identical, report.first_difference


def test_starts_that_reach_the_best_elsewhere_are_said_and_a_swap_is_named():
    """The waterfall's end points: two lags in series reach the best at (1, 2) and (2, 1),
    and the stop reason says the fit does not tell which is which; the best reached along
    a valley is named as parameters it does not fix; a start above the margin, or one at
    the best point itself, adds nothing."""
    from rapid_cosim.estimators.multistart import elsewhere

    space = SearchSpace(("T1", "T3", "R"), np.array([0.1, 0.1, 0.0]), np.array([5.0, 5.0, 1.0]))
    best = np.array([1.0, 2.0, 0.5])
    u = space.to_unit(np.array([best, [2.0, 1.0, 0.5], [1.5, 1.5, 0.9], [1.0, 2.0, 0.5]]))
    said = elsewhere(space, u, np.array([1.0, 1.00005, 3.0, 1.0]), 1e-4, best)
    assert said == "; 1 of them at T1 and T3 exchanged (1 and 2 either way round): the fit does not tell which is which"
    valley = elsewhere(space, u[[0, 2]], np.array([1.0, 1.0]), 1e-4, best)
    assert "1 of them elsewhere (T1 1 and 1.5, T3 2 and 1.5, R 0.5 and 0.9)" in valley
    assert elsewhere(space, u[[0, 1, 3]], np.array([1.0, 1.1, 1.0]), 1e-4, best) == ""


def test_a_run_with_one_optimum_adds_nothing_to_its_stop_reason():
    space = SearchSpace(("T1", "T3", "R"), np.array([0.1, 0.1, 0.0]), np.array([5.0, 5.0, 1.0]))
    unique = multistart(Residuals(lambda X: X - np.array([1.0, 2.0, 0.5])), space, rng=np.random.default_rng(1))
    assert unique.stop_reason.endswith("reached the best")


def test_a_point_scored_before_is_not_simulated_again_and_the_run_is_as_if_it_were():
    """The starts were scored in the design, and a start held by its damping tries its own
    point and the last iteration's largest step again: those rows are recorded as before,
    with the scores they had, but not given to the objective again (a set's score does not
    depend on its batch). Each recorded score is the one the point gets alone."""
    batches = []

    class Alone(Residuals):  # every row scored by itself: what a new simulation gives
        def residuals(self, X):
            X = np.atleast_2d(X)
            batches.append(X.copy())
            R = np.vstack([self.f(x[None]) for x in X])
            fit = np.sum(R ** 2, axis=1)
            return Evaluations(fit, fit[:, None], np.zeros(len(fit), bool)), R

    res = multistart(Alone(_narrow), SPACE, rng=np.random.default_rng(0))
    given = np.vstack(batches)
    recorded = np.vstack([it.x for it in res.history])
    n_starts = len(res.history[-1].extras["start_fun"])
    assert res.nfev == len(given) and len(recorded) - len(given) > n_starts  # the starts and more not simulated
    design = {x.tobytes() for x in batches[0]}
    assert not any(x.tobytes() in design for b in batches[1:] for x in b)
    for it in res.history:
        for x, f in zip(it.x, it.fitness):
            assert f == np.sum(_narrow(x[None]) ** 2)


def test_a_set_runs_its_second_wave_only_where_the_first_does_not_settle_it():
    """Issue 54's waves: on one broad basin the best-screened half of the starts reaches the
    best from across the box, and the rest are not run; asked for starts that set out
    further apart than the half's (spread 1.0, the whole box), the rest run as they always
    did, to the same optimum."""
    space = SearchSpace(("T1", "T3", "R"), np.array([0.1, 0.1, 0.0]), np.array([5.0, 5.0, 1.0]))
    bowl = lambda X: X - np.array([1.0, 2.0, 0.5])  # noqa: E731
    runs = {}
    for waves, spread in ((2, 0.25), (2, 1.0), (1, 0.25)):
        obj = Residuals(bowl)
        res = multistart(obj, space, options=MSOptions(waves=waves, spread=spread), rng=np.random.default_rng(1))
        runs[waves, spread] = (res, len(res.history[-1].extras["start_fun"]), sum(len(p) for p in obj.points))
    (cut, n_cut, sims_cut), (held, n_held, _), (whole, n_whole, sims_whole) = runs.values()
    assert n_whole == 4 + 2 * 3  # the set of 4 + 2d (no x0 given)
    assert n_held == n_whole and n_cut == int(np.ceil(n_whole / 2)) and sims_cut < sims_whole
    assert cut.x == pytest.approx(whole.x, abs=1e-6) and held.x == pytest.approx(whole.x, abs=1e-6)


def test_a_level_ridge_settles_in_the_first_wave():
    """Where every start ends at the best fitness, at several points (T1 + T3 fixed, their
    split free), the ridge is level: a parameter the data leave free, and the first wave
    settles the set."""
    space = SearchSpace(("T1", "T3", "R"), np.array([0.1, 0.1, 0.0]), np.array([5.0, 5.0, 1.0]))
    level = lambda X: np.column_stack([X[:, 0] + X[:, 1] - 3.0, X[:, 2] - 0.5, np.ones(len(X))])  # noqa: E731
    res = multistart(Residuals(level), space, options=MSOptions(waves=2), rng=np.random.default_rng(1))
    assert len(res.history[-1].extras["start_fun"]) == int(np.ceil((4 + 2 * 3) / 2))
    assert "elsewhere" in res.stop_reason


@pytest.mark.parametrize("ends, fun, origins, settled", [
    ("one point", [1.0, 1.0, 1.0, 1.5], "apart", True),
    ("a sloping ridge", [1.0, 1.0, 1.0, 1.5], "apart", False),  # others fall short: more starts may extend it
    ("a level ridge", [1.0, 1.0, 1.0, 1.0], "apart", True),
    ("one point", [1.0, 1.0, 1.0, 1.5], "side by side", False),
    ("one point", [1.0, 1.0, 1.2, 1.5], "apart", False),  # two at the best, min_reached 3
])
def test_when_a_wave_settles_the_set(ends, fun, origins, settled):
    """The settling rule (issue 54): ``min_reached`` starts at the best fitness, set out at
    least ``spread`` apart, ending at one point or every start at the best; where several
    points reach it and other starts fall short (a sloping ridge: a fleet unit's
    rate-limited IEEEG1 stopped short of its optimum), the rest of the set runs."""
    space = SearchSpace(("T1", "T3"), np.array([0.0, 0.0]), np.array([1.0, 1.0]))
    u = np.array([[0.5, 0.5]] * 4) if ends == "one point" else np.array([[0.2, 0.8], [0.5, 0.5], [0.8, 0.2], [0.1, 0.1]])
    o = np.array([[0.1, 0.1], [0.9, 0.5], [0.5, 0.9], [0.3, 0.3]]) if origins == "apart" else \
        np.array([[0.5, 0.5], [0.55, 0.5], [0.5, 0.55], [0.3, 0.3]])
    starts = _Starts()
    starts.u, starts.f, starts.origins = [u], [np.array(fun)], [o]
    best = space.from_unit(u[int(np.argmin(fun))])
    assert starts.settled(space, best, MSOptions()) is settled


def test_waves_and_spread_are_checked():
    with pytest.raises(ValueError, match="waves"):
        MSOptions(waves=0)
    with pytest.raises(ValueError, match="spread"):
        MSOptions(spread=1.5)
