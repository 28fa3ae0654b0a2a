"""Bounded Levenberg-Marquardt on residual vectors, many starting points in lockstep.

Why our own and not ``scipy.optimize.least_squares``: a calibration's cost is its
simulations, and the runner is fastest on large batches. scipy's solver asks for one
point (or one Jacobian) at a time; here every iteration gathers, over all starts still
running, the trial steps into one objective call and the finite-difference Jacobians
(``d`` points per start) into another, so a multistart of 20 starts costs two batched
calls per iteration, which a parallel engine spreads over its workers.

The method, per start, in unit coordinates (each parameter scaled to [0, 1] by its
bounds, log-scaled ones by their logarithm):

* Jacobian ``J`` of the residual vector by forward differences of ``fd_step`` (backward
  at the upper bound), a batch of ``d`` simulations; between two of them (at most
  ``broyden_every`` accepted steps apart) Broyden's rank-one update carries it along
  at no cost, and a step that an updated Jacobian misled, or that looks converged,
  takes a fresh one: convergence is only declared on a Jacobian taken at the point;
* steps ``(J'J + lam diag(J'J)) delta = -J' r`` for three damping values ``lam/10, lam,
  10 lam`` at once, clipped into the box; a coordinate on a bound whose gradient points
  out of the box is held there for the step;
* the best trial is taken if it lowers the fitness (``lam`` follows it), else ``lam``
  grows tenfold; a start stops when the fitness falls by less than ``ftol`` (relative)
  in an accepted step, the step is shorter than ``xtol``, ``lam`` exceeds ``lam_max``, or
  after ``max_iter`` iterations;
* two running starts closer than ``merge_tol`` (largest coordinate difference) are in
  one basin: the worse stops, merged into the better, and shares its end point;
* a point scored before (a start's own point, a trial of the last iteration, a start
  scored in a multistart's design) is recorded with its score, not simulated again:
  a set's score does not depend on its batch, so the run is the one it would be.

Coordinates listed in ``fixed`` are never moved (a profile holds one parameter at each
value of a grid). Deterministic: no randomness, ties broken by start index.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import Tracker, check_option


@dataclass(frozen=True)
class LMOptions:
    max_iter: int = 40
    fd_step: float = 1e-3
    ftol: float = 1e-5  # relative: at 4000 samples, 0.04 in the criterion
    xtol: float = 1e-5
    lam0: float = 1e-3
    lam_max: float = 1e8
    merge_tol: float = 0.03
    broyden_every: int = 4  # a finite-difference Jacobian at least every this many accepted steps (0: always)

    def __post_init__(self):
        check_option("max_iter", self.max_iter, low=1, integer=True)
        check_option("fd_step", self.fd_step, low=0.0, high=0.1, low_open=True)
        check_option("ftol", self.ftol, low=0.0)
        check_option("xtol", self.xtol, low=0.0)
        check_option("lam0", self.lam0, low=0.0, low_open=True)
        check_option("lam_max", self.lam_max, low=0.0, low_open=True)
        check_option("merge_tol", self.merge_tol, low=0.0)
        check_option("broyden_every", self.broyden_every, low=0, integer=True)


RUNNING, CONVERGED, STALLED, MERGED, FAILED, MAX_ITER = range(6)
STATUS = ("running", "converged", "no descent", "merged", "failed", "iteration limit")


@dataclass
class LMRun:
    """What happened to each start: its end point, fitness and status (``merged_into``
    is the start whose basin it joined, -1 otherwise)."""

    u: np.ndarray  # (starts, d) end points, unit coordinates
    f: np.ndarray  # (starts,)
    status: np.ndarray  # (starts,) codes of STATUS
    merged_into: np.ndarray  # (starts,)
    iterations: np.ndarray  # (starts,)


def _evaluate(t: Tracker, P: np.ndarray, known: dict[bytes, tuple] | None = None):
    """(fitness, failed, residual rows) of the points ``P`` (unit coordinates): each
    distinct point not in ``known`` (a row's bytes -> its fitness, failed flag and
    residual row) simulated once, all in one objective call. A set's score does not
    depend on the rows beside it, so a point taken from ``known`` or scored once for two
    rows has the numbers a simulation of it would give: a start held on a bound tries
    its own point again, and a multistart's starts were scored in its design."""
    known = known or {}
    keys = [p.tobytes() for p in P]
    todo: dict[bytes, int] = {}
    for i, k in enumerate(keys):
        if k not in known and k not in todo:
            todo[k] = i
    scored = {}
    if todo:
        ev, R = t.evaluate_residuals(P[list(todo.values())])
        if len(todo) == len(P):  # every row new: as scored, not copied again
            return np.asarray(ev.fitness, dtype=float), np.asarray(ev.failed, dtype=bool), R
        scored = {k: (ev.fitness[j], ev.failed[j], R[j]) for j, k in enumerate(todo)}
    rows = [scored[k] if k in scored else known[k] for k in keys]
    return (np.array([r[0] for r in rows], dtype=float), np.array([r[1] for r in rows], dtype=bool),
            np.vstack([r[2] for r in rows]))


def _jacobians(t: Tracker, U: np.ndarray, R: np.ndarray, idx: list[int], free: np.ndarray, h: float,
               stage_points: list, stage_f: list, stage_failed: list) -> dict[int, np.ndarray]:
    """Forward-difference Jacobians at the points ``U[idx]`` (residuals ``R[idx]``), all in
    one objective call; a start whose stencil fails gets None."""
    points, owners, dirs = [], [], []
    for s in idx:
        for j in np.flatnonzero(free[s]):
            step = h if U[s, j] + h <= 1.0 else -h
            p = U[s].copy()
            p[j] += step
            points.append(p)
            owners.append((s, j))
            dirs.append(step)
    out: dict[int, np.ndarray] = {s: np.zeros((R.shape[1], U.shape[1])) for s in idx}
    if not points:
        return out
    P = np.array(points)
    ev, RP = t.evaluate_residuals(P)
    stage_points.append(P), stage_f.append(ev.fitness), stage_failed.append(ev.failed)
    bad = set()
    for k, (s, j) in enumerate(owners):
        if ev.failed[k] or not np.all(np.isfinite(RP[k])):
            bad.add(s)
            continue
        out[s][:, j] = (RP[k] - R[s]) / dirs[k]
    for s in bad:
        out[s] = None
    return out


def _steps(J: np.ndarray, r: np.ndarray, u: np.ndarray, free: np.ndarray, lams) -> list[np.ndarray]:
    """The damped Gauss-Newton step for each damping in ``lams``: the normal equations are
    formed once for all of them (they do not depend on the damping)."""
    g = J.T @ r
    move = free.copy()
    move &= ~((u <= 0.0) & (g > 0)) & ~((u >= 1.0) & (g < 0))  # held on a bound it pushes against
    if not move.any():
        return [np.zeros_like(u) for _ in lams]
    A = J[:, move].T @ J[:, move]
    D = np.maximum(np.diag(A), 1e-12 * max(float(np.max(np.diag(A))), 1e-300))
    systems = np.array([A + lam * np.diag(D) for lam in lams])
    try:  # one call for the dampings: LAPACK solves each system as it would alone
        solved = np.linalg.solve(systems, np.broadcast_to(-g[move][:, None], (len(lams), int(move.sum()), 1)))[..., 0]
    except np.linalg.LinAlgError:
        solved = None
    out = []
    for i, lam in enumerate(lams):
        delta = np.zeros_like(u)
        if solved is not None:
            delta[move] = solved[i]
        else:
            try:
                delta[move] = np.linalg.solve(systems[i], -g[move])
            except np.linalg.LinAlgError:
                delta[move] = -g[move] / (D * (1 + lam))
        out.append(delta)
    return out


def levenberg_marquardt(t: Tracker, U0: np.ndarray, options: LMOptions = LMOptions(),
                        fixed: np.ndarray | None = None, extras_every=None,
                        known: dict[bytes, tuple] | None = None) -> LMRun:
    """Run LM from every row of ``U0`` (unit coordinates) in lockstep, recording one
    iteration per lockstep step through the tracker. ``fixed`` (starts, d) marks
    coordinates held at their start value. ``extras_every(run)`` may add arrays to each
    recorded iteration (``run`` as it stands, merged starts at their basin's point).
    ``known``: starts scored already (:func:`_evaluate`), not simulated again."""
    o = options
    n, d = U0.shape
    U = np.clip(np.array(U0, dtype=float), 0.0, 1.0)
    free = ~np.asarray(fixed, dtype=bool) if fixed is not None else np.ones((n, d), dtype=bool)
    lam = np.full(n, o.lam0)
    status = np.full(n, RUNNING)
    merged = np.full(n, -1)
    iters = np.zeros(n, dtype=int)
    pts, fs, fails = [], [], []
    f, failed0, R = _evaluate(t, U, known)
    pts.append(U.copy()), fs.append(f.copy()), fails.append(failed0)
    status[failed0 | ~np.all(np.isfinite(R), axis=1)] = FAILED
    live = [s for s in range(n) if status[s] == RUNNING]
    J = _jacobians(t, U, R, live, free, o.fd_step, pts, fs, fails)
    for s in live:
        if J[s] is None:
            status[s] = FAILED
    run = LMRun(U, f, status, merged, iters)

    def record():
        u_end, f_end = _shared(U, f, merged)
        extras = {"start_u": u_end, "start_fun": f_end, "start_status": status.copy()}
        if extras_every is not None:
            extras.update(extras_every(LMRun(u_end, f_end, status.copy(), merged.copy(), iters.copy())))
        t.record(np.vstack(pts), np.concatenate(fs), np.concatenate(fails), None, extras)
        pts.clear(), fs.clear(), fails.clear()

    tried: dict[bytes, tuple] = {}  # the last iteration's trials, scored
    fresh = np.ones(n, dtype=bool)  # J of the start is a finite-difference one taken at its point
    since = np.zeros(n, dtype=int)  # accepted steps since that one
    record()
    for _ in range(o.max_iter):
        live = [s for s in range(n) if status[s] == RUNNING]
        if not live:
            break
        trials, owner, lams = [], [], []
        for s in live:
            factors = [lam[s] * factor for factor in (0.1, 1.0, 10.0)]
            for lam_s, delta in zip(factors, _steps(J[s], R[s], U[s], free[s], factors)):
                trials.append(np.clip(U[s] + delta, 0.0, 1.0))
                owner.append(s)
                lams.append(lam_s)
        T = np.array(trials)
        # a start's own point and the last iteration's trials (a damping raised a
        # hundredfold tries the last one's largest again) are not simulated again
        tried.update({U[s].tobytes(): (f[s], False, R[s]) for s in live})
        fT, failedT, RT = _evaluate(t, T, tried)
        tried = {T[k].tobytes(): (fT[k], failedT[k], RT[k]) for k in range(len(T))}
        pts.append(T), fs.append(fT), fails.append(failedT)
        refresh = []  # starts whose Jacobian is taken again by finite differences
        for s in live:
            iters[s] += 1
            rows = [k for k, o_ in enumerate(owner) if o_ == s and not failedT[k] and np.all(np.isfinite(RT[k]))]
            best = min(rows, key=lambda k: (fT[k], k)) if rows else None
            if best is not None and fT[best] < f[s]:
                gain = f[s] - fT[best]
                step = T[best] - U[s]
                done = gain <= o.ftol * max(abs(fT[best]), 1e-300) or np.max(np.abs(step)) < o.xtol
                if done and fresh[s]:
                    status[s] = CONVERGED  # on a Jacobian taken at the point, never on an updated one
                elif not done and o.broyden_every and since[s] + 1 < o.broyden_every:
                    # Broyden's rank-one update: J follows what the step showed, no simulation
                    J[s] = J[s] + np.outer(RT[best] - R[s] - J[s] @ step, step) / float(step @ step)
                    fresh[s], since[s] = False, since[s] + 1
                else:
                    refresh.append(s)
                U[s], f[s], R[s] = T[best], fT[best], RT[best]
                lam[s] = max(lams[best] * 0.3, 1e-12)
            elif not fresh[s]:
                refresh.append(s)  # an updated Jacobian misled the step: take it again before damping more
            else:
                lam[s] *= 100.0  # the largest trial (10 lam) failed too
                if lam[s] > o.lam_max or (rows and max(np.max(np.abs(T[k] - U[s])) for k in rows) < o.xtol):
                    status[s] = STALLED
            if status[s] == RUNNING and iters[s] >= o.max_iter:
                status[s] = MAX_ITER
        _merge(U, f, status, merged, o.merge_tol)
        refresh = [s for s in refresh if status[s] == RUNNING]
        if refresh:
            newJ = _jacobians(t, U, R, refresh, free, o.fd_step, pts, fs, fails)
            for s in refresh:
                if newJ[s] is None:
                    status[s] = FAILED
                else:
                    J[s], fresh[s], since[s] = newJ[s], True, 0
        record()
    status[status == RUNNING] = MAX_ITER
    run.u, run.f = _shared(U, f, merged)
    return run


def _shared(U, f, merged):
    """End points and fitness with each merged start given those of the start it joined."""
    U, f = U.copy(), f.copy()
    for s in range(len(f)):
        k = s
        while merged[k] >= 0:
            k = merged[k]
        U[s], f[s] = U[k], f[k]
    return U, f


def _merge(U, f, status, merged, tol: float) -> None:
    live = [s for s in range(len(f)) if status[s] == RUNNING or status[s] in (CONVERGED, STALLED, MAX_ITER)]
    running = [s for s in live if status[s] == RUNNING]
    for a in running:
        if status[a] != RUNNING:
            continue
        for b in live:
            if b == a or status[b] == MERGED:
                continue
            if np.max(np.abs(U[a] - U[b])) < tol and (f[b], b) < (f[a], a):
                status[a], merged[a] = MERGED, b
                break
