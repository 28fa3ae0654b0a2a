"""Which estimated parameters do the tests determine? The Fisher information at the
optimum, from the prewhitened residuals' sensitivities.

For parameters ``theta`` (in the log of their value for log-scaled ones, so that a
standard error reads as a relative one), ``J`` holds the derivatives of every test's
residual, prewhitened with its noise ``phi`` and divided by the innovation level, by
central differences (steps of 1 % of the value, one-sided at a bound). ``F = J^T J``
is the information, its inverse the covariance of a least-squares estimate under the noise model (a lower bound:
a structure that misfits has more), its condition number the spread of what is and is
not determined. Each parameter is

* **determined**: relative standard error under 10 %;
* **weakly determined**: 10 to 50 %;
* **not determined**: over 50 %, or F singular in its direction.

Pairs whose estimates correlate beyond 0.9 in magnitude trade off: the tests move them
together (e.g. a gain against a time constant); :func:`best_separating_step` proposes
the staged step that most reduces the weakest parameter's error.

Pairs that **exchange** are what the information cannot show: swapping their values
leaves the fit as it is, so the optimum is sharp and still not unique. Two lags in series
with no limit acting between them are such a pair, as the response depends only on their
sum and product: TG Type I's servo Ts and reheater T5 with its T5 estimated, IEEEG1's
servo T3 and steam chest T4, TGOV1's valve T1 and reheater T3. The tests then determine
the two values, not which is which (on the ANDES event tgtypei_off_b with T5 free, 14
of 100 noise draws put Ts at the reheater's 4.5 s and T5 at the servo's 1.2 s); a rate or
position limit that acts on the first lag tells them apart, and the check then finds no
exchange.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..diagnose.exchanges import exchanges, whitened_residual
from ..simulator import get_simulator

REL_DETERMINED = 0.10
REL_WEAK = 0.50
TRADE_OFF = 0.9
STEP = 0.01


@dataclass(frozen=True)
class Identifiability:
    names: tuple[str, ...]
    relative_se: np.ndarray
    correlation: np.ndarray
    condition: float
    information: np.ndarray  # F, per relative change of each parameter
    exchanges: tuple[tuple[str, str, float], ...] = ()  # pairs whose swap leaves the fit (change of the sum of squares)

    @property
    def relative_se_by_name(self) -> dict[str, float]:
        return {n: float(self.relative_se[k]) for k, n in enumerate(self.names)}

    def status(self, k: int) -> str:
        r = self.relative_se[k]
        return ("determined" if r < REL_DETERMINED else "weakly determined" if r < REL_WEAK
                else "not determined")

    @property
    def trade_offs(self) -> list[tuple[str, str, float]]:
        n = len(self.names)
        return [(self.names[i], self.names[j], float(self.correlation[i, j])) for i in range(n)
                for j in range(i + 1, n) if abs(self.correlation[i, j]) > TRADE_OFF]

    def summary(self) -> str:
        weak = [f"{n} {self.status(k)}" for k, n in enumerate(self.names) if self.status(k) != "determined"]
        weak += [f"{a} and {b} exchange (the tests fit them either way round)" for a, b, _ in self.exchanges]
        return ("every parameter determined" if not weak else "; ".join(weak)) + f" (condition {self.condition:.2g})"

    def to_json(self) -> dict:
        return {"parameters": {n: {"relative_se": float(self.relative_se[k]), "status": self.status(k)}
                               for k, n in enumerate(self.names)},
                "trade_offs": [{"a": a, "b": b, "correlation": c} for a, b, c in self.trade_offs],
                "exchanges": [{"a": a, "b": b, "change": c} for a, b, c in self.exchanges],
                "condition": self.condition, "correlation": self.correlation.tolist()}


def _covariance(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(covariance, standard errors) from the information ``F``; a parameter with a part
    in a direction the tests do not see at all gets an infinite standard error."""
    cov = np.linalg.pinv(F, rcond=NULL_RCOND, hermitian=True)
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    vals, vecs = np.linalg.eigh(F)
    null = vals <= NULL_RCOND * max(float(vals.max()), 1e-300)
    blind = np.any(np.abs(vecs[:, null]) > 1e-3, axis=1) if null.any() else np.zeros(F.shape[0], dtype=bool)
    return cov, np.where(blind | (np.diag(F) <= 0), np.inf, se)


def _pair(inputs, x: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, float]:
    """The points either side of ``x`` along parameter ``k`` (a 1 % step, kept inside
    the declared bounds: one-sided at a bound) and their distance."""
    h = STEP * (abs(x[k]) if x[k] != 0 else 1.0)
    space = inputs.problem.space
    up, down = x.copy(), x.copy()
    up[k], down[k] = min(x[k] + h, space.upper[k]), max(x[k] - h, space.lower[k])
    return up, down, up[k] - down[k]


def identifiability(inputs, x: np.ndarray, noise) -> Identifiability:
    """At ``x`` (the run's best point, physical units) for the run's estimated parameters."""
    x = np.asarray(x, dtype=float)
    cols = []
    for k in range(x.size):
        up, down, width = _pair(inputs, x, k)
        d = (whitened_residual(inputs, up, noise) - whitened_residual(inputs, down, noise)) / width
        cols.append(d * (abs(x[k]) if x[k] != 0 else 1.0))  # per relative change: d/d(log theta)
    J = np.column_stack(cols)
    F = J.T @ J
    s = np.linalg.svd(F, compute_uv=False)
    condition = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    cov, se = _covariance(F)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    corr = np.nan_to_num(corr)
    np.fill_diagonal(corr, 1.0)
    return Identifiability(tuple(inputs.problem.names), se, corr, condition, F, exchanges(inputs, x, noise))


# Information below this share of the largest is none: a limit never reached changes the
# simulated output by rounding only, and its direction must read "not determined", not be
# cut from the inverse and read as perfectly determined.
NULL_RCOND = 1e-12

STEPS_HZ = (-0.4, -0.2, -0.1, 0.1, 0.2, 0.4)
HOLD_S = 50.0


@dataclass(frozen=True)
class DeterminingStep:
    """The staged step that most determines a structure's least determined parameter:
    that parameter, its relative error now and with the step's test added, the step's
    size, the advice in words, and every step tried (``menu``: (df_hz, relative_se))."""

    parameter: str
    relative_se_now: float
    df_hz: float
    relative_se: float
    advice: str
    menu: tuple[tuple[float, float], ...]

    def to_json(self) -> dict:
        """As structures.json holds it."""
        return {"parameter": self.parameter, "relative_se_now": self.relative_se_now, "df_hz": self.df_hz,
                "relative_se": self.relative_se, "advice": self.advice,
                "menu": [{"df_hz": df, "relative_se": se} for df, se in self.menu]}


def best_separating_step(inputs, x: np.ndarray, ident: Identifiability, noise) -> DeterminingStep | None:
    """The staged step (size, held HOLD_S and returned, at the first test's dispatch and
    sampling) that most reduces the least determined parameter's relative error once
    added to the tests; None when every parameter is determined."""
    k = int(np.argmax(ident.relative_se))
    if ident.status(k) == "determined":
        return None
    i = next((j for j, e in enumerate(inputs.problem.experiments) if not e.inputs), None)
    if i is None:
        return None
    exp = inputs.problem.experiments[i]
    sim = get_simulator(inputs.fmus[exp.model])
    x = np.asarray(x, dtype=float)
    t_step = float(exp.fixed.get("src.t_step", 10.0))
    dt = float(np.median(np.diff(exp.data.time)))
    times = np.arange(0.0, t_step + 2 * HOLD_S, dt)
    floor = noise[exp.name]
    rows = []
    for df in STEPS_HZ:
        cols = []
        for j in range(x.size):
            *points, width = _pair(inputs, x, j)
            ys = []
            for xx in points:
                params = {**inputs.problem.parameters_for(xx, i), "src.df": df, "src.t_step": t_step,
                          "src.t_return": t_step + HOLD_S}
                ys.append(sim.simulate(params, output_times=times, outputs=list(exp.outputs))[next(iter(exp.outputs))])
            d = (ys[0] - ys[1]) / width * (abs(x[j]) if x[j] != 0 else 1.0)
            cols.append(floor.whiten(d - d.mean()))  # offsets are profiled
        J = np.column_stack(cols)
        rows.append((df, float(_covariance(ident.information + J.T @ J)[1][k])))
    best_df, best_se = min(rows, key=lambda r: r[1])
    name = ident.names[k]
    now = f"{name} is {ident.status(k)} ({100 * ident.relative_se[k]:.0f} % relative error)"
    step = f"df = {1000 * best_df:+.0f} mHz, held {HOLD_S:.0f} s and returned"
    advice = (f"{now}: a staged test with {step}, brings it to {100 * best_se:.0f} %"
              if best_se < REL_WEAK else
              f"{now}, and no staged step of {min(STEPS_HZ):+.1f} to {max(STEPS_HZ):+.1f} Hz determines it (the "
              f"best, {step}, leaves {100 * best_se:.0f} %): fix it from the documentation or a test "
              f"that engages it")
    return DeterminingStep(name, float(ident.relative_se[k]), best_df, best_se, advice, tuple(rows))

