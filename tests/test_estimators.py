"""Estimators on analytic problems: convergence, bounds, failures, determinism, replay,
chain book-keeping and option checks. SMC posterior checks are in test_estimators_smc.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rapid_cosim.estimators import (GDOptions, NMOptions, PFOptions, PSOOptions, ScanOptions, SearchSpace,
                                    SMCOptions, Evaluations, Stage, parse_method,
                                    particle_filter, run_chain)

# droop-like and time-constant-like parameters on very different scales
SPACE = SearchSpace(("R", "Ts"), np.array([0.02, 0.1]), np.array([0.1, 20.0]))
X_STAR = np.array([0.05, 5.0])
SCALE = np.array([0.01, 2.0])


def bowl_values(X, x_star=X_STAR):
    """Correlated quadratic bowl, minimum 0 at ``x_star``."""
    z = (X - x_star) / SCALE
    return z[:, 0] ** 2 + z[:, 1] ** 2 + 0.8 * z[:, 0] * z[:, 1]


def valley_values(X):
    """Curved (Rosenbrock-like) valley Ts - 5 ~ 4 ((R - 0.05)/0.02)^2, minimum 0 at X_STAR."""
    a = (X[:, 0] - 0.05) / 0.02
    b = (X[:, 1] - 5.0) / 4.0
    return a**2 + 20.0 * (b - a**2) ** 2


def bowl(X):
    return Evaluations.from_fitness(bowl_values(X))


def valley(X):
    return Evaluations.from_fitness(valley_values(X))


def loglik(ev):
    return -0.5 * ev.rssd[:, 0] / 0.05


class Recorder:
    """Wraps an objective, keeping every batch it was given and what it returned."""

    def __init__(self, objective):
        self.objective, self.calls, self.values = objective, [], []

    def __call__(self, X):
        self.calls.append(np.array(X, copy=True))
        ev = self.objective(X)
        self.values.append(ev)
        return ev

    @property
    def rows(self):
        return np.vstack(self.calls)


class Replay:
    """Returns recorded values in order and fails if the calls differ from the recording."""

    def __init__(self, recorder):
        self.recorder, self.k = recorder, 0

    def __call__(self, X):
        assert self.k < len(self.recorder.calls), "more calls than in the recording"
        np.testing.assert_array_equal(X, self.recorder.calls[self.k])
        ev = self.recorder.values[self.k]
        self.k += 1
        return ev


def run(method, objective, seed=3, **kw):
    return run_chain(objective, SPACE, method, rng=np.random.default_rng(seed),
                     log_likelihood=loglik, **kw)


def unit_error(x, x_star=X_STAR):
    return float(np.max(np.abs(SPACE.to_unit(x) - SPACE.to_unit(x_star))))


ALL_METHODS = ["pf", "pso", "nm", "gd", "smc", "pf:10+nm", "pso:10+nm", "pf:5+pso:5+gd", "pso:5+nm+scan+nm"]

# tolerance on the optimum in unit coordinates (fraction of each parameter's range)
RECOVERY = [("pf", 0.01), ("pso", 1e-4), ("nm", 1e-5), ("gd", 1e-5),
            ("pf:10+nm", 1e-5), ("pso:10+nm", 1e-5), ("pf:5+pso:5+gd", 1e-5)]


@pytest.mark.parametrize("problem", [bowl, valley], ids=["bowl", "valley"])
@pytest.mark.parametrize("method,tol", RECOVERY, ids=[m for m, _ in RECOVERY])
def test_recovers_optimum(method, tol, problem):
    res = run(method, problem)
    assert unit_error(res.x) < tol, (res.x, res.stop_reason)
    assert res.fun == pytest.approx(float(problem(res.x[None, :]).fitness[0]))
    assert res.method == method


def test_smc_best_point_near_optimum():
    res = run("smc", bowl)
    assert unit_error(res.x) < 0.01
    assert unit_error(res.uncertainty.mean) < 0.01


@pytest.mark.parametrize("method", ALL_METHODS)
def test_same_seed_same_run_bit_for_bit(method):
    a, b = run(method, bowl, seed=11), run(method, bowl, seed=11)
    np.testing.assert_array_equal(a.x, b.x)
    assert (a.fun, a.nfev, a.nit, a.stop_reason) == (b.fun, b.nfev, b.nit, b.stop_reason)
    assert len(a.history) == len(b.history)
    for ia, ib in zip(a.history, b.history):
        keys = ("stage", "index", "n_sims", "rng_state")
        assert [getattr(ia, k) for k in keys] == [getattr(ib, k) for k in keys]
        for field in ("x", "fitness", "weights", "failed", "best_x"):
            np.testing.assert_array_equal(getattr(ia, field), getattr(ib, field))
        assert ia.best_fitness == ib.best_fitness or np.isnan(ia.best_fitness)
        assert ia.extras.keys() == ib.extras.keys()
        for key in ia.extras:
            np.testing.assert_array_equal(ia.extras[key], ib.extras[key])
    if a.uncertainty is not None:
        np.testing.assert_array_equal(a.uncertainty.samples, b.uncertainty.samples)
        np.testing.assert_array_equal(a.uncertainty.weights, b.uncertainty.weights)


def test_different_seeds_differ():
    a, b = run("pf", bowl, seed=1), run("pf", bowl, seed=2)
    assert not np.array_equal(a.history[0].x, b.history[0].x)


@pytest.mark.parametrize("method", ALL_METHODS)
def test_replay_with_cached_values_makes_identical_calls(method):
    # a noisy objective: re-running it would give other values, replaying must not
    noise = np.random.default_rng(99)

    def noisy(X):
        return Evaluations.from_fitness(bowl_values(X) * (1 + 0.01 * noise.standard_normal(len(X))))

    rec = Recorder(noisy)
    first = run(method, rec, seed=5)
    replay = Replay(rec)
    second = run(method, replay, seed=5)
    assert replay.k == len(rec.calls)
    np.testing.assert_array_equal(first.x, second.x)
    assert [i.rng_state for i in first.history] == [i.rng_state for i in second.history]


@pytest.mark.parametrize("method", ALL_METHODS)
def test_every_evaluated_point_is_inside_the_bounds(method):
    # optimum outside the box (beyond both upper bounds): methods press on the corner
    corner = np.array([0.1, 20.0])
    rec = Recorder(lambda X: Evaluations.from_fitness(bowl_values(X, np.array([0.12, 24.0]))))
    res = run(method, rec)
    assert np.all(SPACE.contains(rec.rows))
    assert all(np.all(SPACE.contains(it.x)) for it in res.history)
    if method in ("nm", "gd", "pf:10+nm", "pso:10+nm", "pf:5+pso:5+gd", "pso:5+nm+scan+nm"):
        assert unit_error(res.x, corner) < 1e-4


def test_pf_reflection_does_not_pile_particles_on_the_bounds():
    rec = Recorder(lambda X: Evaluations.from_fitness(bowl_values(X, np.array([0.12, 24.0]))))
    particle_filter(rec, SPACE, options=PFOptions(max_iter=10), rng=np.random.default_rng(0))
    on_bound = np.any((rec.rows == SPACE.lower) | (rec.rows == SPACE.upper), axis=1)
    assert on_bound.sum() == 0


def failing(kind):
    """The bowl with a failing region (Ts > 12, R < 0.03 and a thin band) that carries
    either a penalty fitness with ``failed`` set, or a NaN fitness."""

    def objective(X):
        f = bowl_values(X)
        bad = (X[:, 1] > 12.0) | (X[:, 0] < 0.03) | ((X[:, 1] > 5.5) & (X[:, 1] < 5.6))
        if kind == "penalty":
            f = np.where(bad, 1e6, f)
            return Evaluations(f, f[:, None].copy(), bad)
        f = np.where(bad, np.nan, f)
        return Evaluations(f, f[:, None].copy(), np.zeros(len(f), dtype=bool))

    return objective


@pytest.mark.parametrize("kind", ["penalty", "nan"])
@pytest.mark.parametrize("method", ALL_METHODS)
def test_failed_evaluations_do_not_break_methods(method, kind):
    rec = Recorder(failing(kind))
    res = run(method, rec)
    n_bad = sum(int((ev.failed | ~np.isfinite(ev.fitness)).sum()) for ev in rec.values)
    assert res.n_failed == n_bad
    assert np.isfinite(res.fun) and res.fun < 1e6
    tol = 0.02 if method in ("pf", "smc") else 1e-4
    assert unit_error(res.x) < tol, (res.x, res.stop_reason)
    for it in res.history:
        assert np.all(it.failed[~np.isfinite(it.fitness)])


@pytest.mark.parametrize("method", ["nm", "gd"])
def test_local_method_starting_in_a_failed_plateau_stops_cleanly(method):
    res = run(method, failing("nan"), x0=np.array([0.05, 15.0]))
    assert res.fun == np.inf and res.n_failed == res.nfev
    assert res.nfev < 200  # stops on the plateau instead of burning its budget


def test_chain_book_keeping():
    rec = Recorder(bowl)
    seen = []
    res = run("pf:4+pso:3+nm", rec, callback=seen.append)
    h = res.history
    assert seen == list(h)
    assert [it.index for it in h] == list(range(len(h))) and res.nit == len(h)
    stages = [it.stage for it in h]
    assert stages[:7] == ["pf"] * 4 + ["pso"] * 3 and set(stages[7:]) == {"nm"}
    sims = [it.n_sims for it in h]
    assert sims == sorted(sims) and sims[-1] == res.nfev == len(rec.rows)
    walls = [it.wall_time for it in h]
    assert walls == sorted(walls)
    best = [it.best_fitness for it in h]
    assert best == sorted(best, reverse=True) and best[-1] == res.fun
    # each stage starts from the previous best: PSO's first swarm and NM's first point hold it
    np.testing.assert_array_equal(h[4].x[0], h[3].best_x)
    np.testing.assert_array_equal(h[7].x[0], h[6].best_x)
    assert "pf (stage 1/3): reached max_iter=4" in res.stop_reason
    assert "pso (stage 2/3): reached max_iter=3" in res.stop_reason
    assert "nm (stage 3/3)" in res.stop_reason
    assert res.method == "pf:4+pso:3+nm"


@pytest.mark.parametrize("method", ALL_METHODS)
def test_rng_state_is_json_and_matches_the_generator(method):
    rng = np.random.default_rng(8)
    res = run_chain(bowl, SPACE, method, rng=rng, log_likelihood=loglik)
    assert json.loads(res.history[-1].rng_state) == rng.bit_generator.state
    restored = np.random.default_rng()
    restored.bit_generator.state = json.loads(res.history[-1].rng_state)
    # a generator restored from the archived state draws what the original draws next
    np.testing.assert_array_equal(restored.uniform(size=8), rng.uniform(size=8))
    np.testing.assert_array_equal(restored.standard_normal(3), rng.standard_normal(3))


def test_pf_keeps_x0_elite_and_decays_kernel():
    x0 = np.array([0.07, 12.0])
    h = particle_filter(bowl, SPACE, options=PFOptions(max_iter=8, kernel_decay=0.5),
                        rng=np.random.default_rng(1), x0=x0).history
    np.testing.assert_allclose(h[0].x[0], x0)
    for prev, it in zip(h, h[1:]):
        np.testing.assert_array_equal(it.x[0], prev.best_x)  # elite carried, not re-simulated
        assert it.fitness[0] == prev.best_fitness and not it.extras["evaluated"][0]
        assert it.extras["sigma_k"] == pytest.approx(0.5 * prev.extras["sigma_k"])
        assert it.best_fitness <= prev.best_fitness
        assert it.n_sims - prev.n_sims == len(it.x) - 1
    assert np.all(h[0].extras["evaluated"])


def test_pf_stops_on_spread_and_fitness_tol():
    res = particle_filter(bowl, SPACE, options=PFOptions(max_iter=500, spread_tol=1e-3),
                          rng=np.random.default_rng(0))
    assert "spread" in res.stop_reason and res.nit < 500
    res = particle_filter(bowl, SPACE, options=PFOptions(max_iter=500, fitness_tol=1e-2),
                          rng=np.random.default_rng(0))
    assert "fitness_tol" in res.stop_reason and res.fun <= 1e-2


def limit_values(X):
    """A limit that acts only when Ts (standing in for it) is below 6: above, a plateau on
    which Ts does not matter; below, a narrow valley (5 % of the range) down to 0 at
    (0.05, 5.5), walled at Ts = 5."""
    ts = X[:, 1]
    r = ((X[:, 0] - 0.05) / 0.01) ** 2
    valley = np.where(ts < 5.0, 1.0 + 10.0 * (5.0 - ts), 4.0 * (ts - 5.5) ** 2)
    return r + np.where(ts >= 6.0, 1.0, valley)


def test_scan_steps_off_a_plateau_into_the_valley_where_a_limit_acts():
    objective = lambda X: Evaluations.from_fitness(limit_values(X))  # noqa: E731
    on_plateau = np.array([0.06, 15.0])
    stuck = run("nm", objective, x0=on_plateau)
    assert stuck.x[1] > 6.0 and stuck.fun == pytest.approx(1.0, abs=1e-6)
    found = run("nm+scan+nm", objective, x0=on_plateau)
    assert found.fun < 1e-8 and found.x == pytest.approx([0.05, 5.5], rel=1e-4)
    scans = [it for it in found.history if it.stage == "scan"]
    # one iteration per parameter and sweep, every sweep over the whole range in one call
    assert [int(it.extras["parameter"]) for it in scans][:2] == [0, 1]
    assert all(len(it.x) == ScanOptions().n_points for it in scans)
    assert scans[1].x[:, 1].min() == pytest.approx(0.1) and scans[1].x[:, 1].max() == pytest.approx(20.0)


def test_pso_stops_on_stagnation():
    flat = lambda X: Evaluations.from_fitness(np.ones(len(X)))  # noqa: E731
    res = run("pso", flat, options={"pso": PSOOptions(stall_iter=5)})
    assert res.nit == 6 and "no improvement" in res.stop_reason


def test_stage_cap_overrides_the_options():
    res = run("pso:3", bowl, options={"pso": PSOOptions(max_iter=50)})
    assert res.nit == 3


def test_nm_evaluates_one_point_per_call_and_groups_by_iteration():
    rec = Recorder(bowl)
    res = run("nm", rec)
    assert all(c.shape == (1, 2) for c in rec.calls)
    assert len(res.history[0].x) >= 3  # initial simplex goes into the first iteration
    assert sum(len(it.x) for it in res.history) == res.nfev == len(rec.calls)


@pytest.mark.parametrize("difference,stencil", [("forward", 2), ("central", 4)])
def test_gd_scores_the_stencil_in_one_call(difference, stencil):
    rec = Recorder(bowl)
    res = run("gd", rec, options={"gd": GDOptions(difference=difference)})
    assert rec.calls[0].shape == (stencil + 1, 2)  # the start point joins the first stencil
    assert stencil in {len(c) for c in rec.calls[1:]}
    tol = 1e-5 if difference == "central" else 1e-3  # forward differences are biased by ~h/2
    assert unit_error(res.x) < tol


def test_parse_method():
    assert parse_method("pf:10+nm") == (Stage("pf", 10), Stage("nm"))
    assert parse_method(" PF:5 + pso:5 + gd ") == (Stage("pf", 5), Stage("pso", 5), Stage("gd"))
    assert parse_method("smc") == (Stage("smc"),)


@pytest.mark.parametrize("text,message", [
    ("", "empty method"),
    ("pf:10+bfgs", "unknown method 'bfgs'.*allowed: pf, smc, pso, nm, gd"),
    ("pf:0+nm", "bad iteration count '0'.*positive integer"),
    ("pf:-3", "bad iteration count '-3'"),
    ("pf:2.5", "bad iteration count '2.5'"),
    ("pf:x+nm", "bad iteration count 'x'"),
    ("pf:", "bad iteration count ''"),
    ("pf++nm", "empty stage 2"),
])
def test_parse_method_errors(text, message):
    with pytest.raises(ValueError, match=message):
        parse_method(text)


def test_run_chain_argument_errors():
    with pytest.raises(ValueError, match="needs log_likelihood"):
        run_chain(bowl, SPACE, "pf:2+smc", rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="must be a PFOptions"):
        run("pf", bowl, options={"pf": PSOOptions()})
    with pytest.raises(ValueError, match="unknown method 'cma'"):
        run("pf", bowl, options={"cma": PFOptions()})
    with pytest.raises(ValueError, match=r"x0 is outside the bounds: Ts=25"):
        run("nm", bowl, x0=np.array([0.05, 25.0]))


@pytest.mark.parametrize("make,message", [
    (lambda: PFOptions(epsilon=1.0), r"epsilon=1.0 is out of range; allowed: 0.0 <= epsilon < 1.0"),
    (lambda: PFOptions(n_particles=1), "n_particles=1"),
    (lambda: PFOptions(kernel_decay=0.0), "kernel_decay"),
    (lambda: PFOptions(sigma_k=-0.1), "sigma_k"),
    (lambda: PSOOptions(v_max=0.0), "v_max"),
    (lambda: PSOOptions(n_particles=2.5), "n_particles=2.5 is not an integer"),
    (lambda: SMCOptions(ess_target=1.0), "ess_target"),
    (lambda: SMCOptions(level=0.0), "level"),
    (lambda: NMOptions(initial_step=0.7), "initial_step"),
    (lambda: GDOptions(difference="backward"), "difference='backward'.*forward.*central"),
    (lambda: ScanOptions(n_points=1), "n_points=1"),
    (lambda: ScanOptions(max_iter=0), "max_iter=0"),
    (lambda: GDOptions(fd_step="0.1"), "fd_step='0.1' is not a number"),
])
def test_options_are_validated(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_objective_returning_wrong_shape_is_reported():
    with pytest.raises(ValueError, match="objective returned fitness"):
        run("pso", lambda X: Evaluations.from_fitness(bowl_values(X)[:1]))


def test_stepped_points_step_each_coordinate_inside_the_box():
    """SearchSpace.stepped: the batch every forward-difference Jacobian is read from (the
    diagnosis's adequacy, the intervals' sandwich, the advice): forward by the step, backward
    at the upper bound, none along a held coordinate, each point in the box."""
    space = SearchSpace(("R", "Ts", "K"), np.array([0.02, 0.1, 1.0]), np.array([0.1, 20.0, 2.0]), (False, True, False))
    u = np.array([0.5, 1.0, 0.25])
    X, steps = space.stepped(u, 1e-3, free=np.array([True, True, False]))
    assert steps.tolist() == [1e-3, -1e-3, 0.0]
    assert X.shape == (4, 3) and np.all(space.contains(X))
    np.testing.assert_allclose(space.to_unit(X[0]), u)
    np.testing.assert_allclose(space.to_unit(X[1]) - u, [1e-3, 0, 0], atol=1e-12)
    np.testing.assert_allclose(space.to_unit(X[2]) - u, [0, -1e-3, 0], atol=1e-12)
    np.testing.assert_array_equal(X[3], X[0])
