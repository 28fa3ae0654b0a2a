"""Independent reference: the test benches' equations written out in numpy and
integrated with scipy, piecewise between the source's switching times.

Written from the paper (eqs. 1-6) and the effect blocks' documented formulas, not from
the generated code, so an FMU that agrees with it is right for the right reason.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

BASE = {
    "src.df": -0.2, "src.f_nom": 50.0, "src.t_step": 10.0, "src.t_return": 1e9,
    "gov.R": 0.05, "gov.Ts": 0.5, "gov.Tc": 0.4, "gov.T3": 0.2, "gov.T4": 1.5, "gov.T5": 6.0,
    "gov.pmax": 1.0, "gov.pmin": 0.0, "gov.p_ref": 0.6,
}
EFFECT_DEFAULTS = {
    "StagedTest": {},
    "StagedTestDeadband": {"db.db": 0.015, "db.f_nom": 50.0, "db.eps_db": 1e-4},
    "StagedTestDelay": {"dly.T": 0.5},
    "StagedTestRateLimit": {"gov.rate_open": 0.01, "gov.rate_close": 0.02, "gov.eps_rate": 1e-4},
    "StagedTestBacklash": {"gov.backlash": 0.01, "gov.T_bl": 0.05, "gov.eps_bl": 1e-4},
    "StagedTestLoadController": {"gov.K_lc": 0.005},
    "StagedTestMeasurementLag": {"meas.T": 0.5, "meas.offset": 0.0},
    "StagedTestOutputLimit": {"lim.headroom": 0.05, "lim.eps_lim": 1e-3},
    "StagedTestLoadControllerFiltered": {"gov.K_lc": 0.005, "gov.T_f": 10.0},
    "StagedTestRateLimitCommand": {"gov.rate_open": 0.01, "gov.rate_close": 0.02, "gov.eps_rate": 1e-4,
                                   "gov.T_rl": 0.02},
}
# extra states of each bench, after xg1, xg2, xg3
EXTRA_STATES = {"StagedTestBacklash": 1, "StagedTestLoadController": 1,
                "StagedTestMeasurementLag": 1, "StagedTestLoadControllerFiltered": 2,
                "StagedTestRateLimitCommand": 1}


def _softplus(z, eps):
    return 0.5 * (z + np.sqrt(z * z + eps * eps))


def _softplus_exp(z, eps):
    return eps * np.logaddexp(0.0, z / eps)


def _limited(p, v):
    """A speed ``v`` through the smooth clamp to [-rate_close, rate_open] (RateLimitedLag)."""
    ro, rc, eps = p["gov.rate_open"], p["gov.rate_close"], p["gov.eps_rate"]
    return v - (_softplus(v - ro, eps) - _softplus(-ro, eps)) + (_softplus(-rc - v, eps) - _softplus(-rc, eps))


def _turbine(p, xv, xg2, xg3):
    T3c, T45 = p["gov.T3"] / p["gov.Tc"], p["gov.T4"] / p["gov.T5"]
    dxg2 = ((1 - T3c) * xv - xg2) / p["gov.Tc"]
    dxg3 = ((1 - T45) * (xg2 + T3c * xv) - xg3) / p["gov.T5"]
    pm = xg3 + T45 * (xg2 + T3c * xv)
    return dxg2, dxg3, pm


class Reference:
    """RHS, output and steady start of one test bench."""

    def __init__(self, bench: str, params: dict):
        self.bench = bench
        self.p = {**BASE, **EFFECT_DEFAULTS[bench], **params}
        # a transport delay moves the step's switching times: y(t) = u(t - T), exactly
        self.p["src.t_delay"] = self.p.get("dly.T", 0.0) if bench == "StagedTestDelay" else 0.0

    def dw(self, t):
        p = self.p
        on = p["src.t_step"] + p["src.t_delay"] <= t < p["src.t_return"] + p["src.t_delay"]
        return -p["src.df"] / p["src.f_nom"] if on else 0.0

    def _governor_input(self, dw, x):
        """Frequency path effects before the governor; returns (dw seen, extra derivs)."""
        p = self.p
        if self.bench == "StagedTestDeadband":
            d, e = p["db.db"] / p["db.f_nom"], p["db.eps_db"] / p["db.f_nom"]
            return dw + 0.5 * (np.sqrt((dw - d) ** 2 + e ** 2) - np.sqrt((dw + d) ** 2 + e ** 2)), []
        return dw, []

    def rhs(self, t, x):
        p = self.p
        dwg, extra = self._governor_input(self.dw(t), x)
        xg1, xg2, xg3 = x[0], x[1], x[2]
        pin_star = p["gov.p_ref"] + dwg / p["gov.R"]
        if self.bench in ("StagedTestLoadController", "StagedTestLoadControllerFiltered"):
            pin_star += x[3]
        pin = min(max(pin_star, p["gov.pmin"]), p["gov.pmax"])
        if self.bench == "StagedTestRateLimitCommand":  # the command ramps (a fast lag with limited speed), then Ts
            ramp = _limited(p, (pin - x[3]) / p["gov.T_rl"])
            v = (x[3] - xg1) / p["gov.Ts"]
        else:
            v = (pin - xg1) / p["gov.Ts"]
        if self.bench == "StagedTestRateLimit":
            v = _limited(p, v)
        xv = x[3] if self.bench == "StagedTestBacklash" else xg1
        dxg2, dxg3, pm = _turbine(p, xv, xg2, xg3)
        d = [v, dxg2, dxg3] + extra
        if self.bench == "StagedTestBacklash":
            h, eps = p["gov.backlash"] / 2, p["gov.eps_bl"]
            gap = xg1 - xv
            d.append((_softplus_exp(gap - h, eps) - _softplus_exp(-gap - h, eps)) / p["gov.T_bl"])
        if self.bench == "StagedTestLoadController":
            d.append(p["gov.K_lc"] * (p["gov.p_ref"] - pm))
        if self.bench == "StagedTestLoadControllerFiltered":  # x[3]: correction, x[4]: filtered power
            d += [p["gov.K_lc"] * (p["gov.p_ref"] - x[4]), (pm - x[4]) / p["gov.T_f"]]
        if self.bench == "StagedTestRateLimitCommand":
            d.append(ramp)
        if self.bench == "StagedTestMeasurementLag":
            d.append((pm - x[3]) / p["meas.T"])
        return np.array(d, dtype=float)

    def output(self, t, x):
        if self.bench == "StagedTestMeasurementLag":
            return x[3] + self.p["meas.offset"]
        xv = x[3] if self.bench == "StagedTestBacklash" else x[0]
        pm = _turbine(self.p, xv, x[1], x[2])[2]
        if self.bench == "StagedTestOutputLimit":  # pm - max(pm - p_ref - headroom, 0), smoothed
            h, eps = self.p["lim.headroom"], self.p["lim.eps_lim"]
            pm = pm - (_softplus(pm - self.p["gov.p_ref"] - h, eps) - _softplus(-h, eps))
        return pm

    def n_states(self):
        return 3 + EXTRA_STATES.get(self.bench, 0)

    def steady_start(self, t0=0.0):
        """Equilibrium at t0 by root finding; states with a continuum of equilibria
        (backlash position, load-controller integral) are pinned as the models pin them."""
        n = self.n_states()
        guess = np.full(n, self.p["gov.p_ref"])
        if self.bench in ("StagedTestLoadController", "StagedTestLoadControllerFiltered"):
            guess[3] = 0.0

        def residual(x):
            r = self.rhs(t0, x)
            if self.bench == "StagedTestBacklash":
                r[3] = x[3] - x[0]
            if self.bench in ("StagedTestLoadController", "StagedTestLoadControllerFiltered"):
                r[3] = x[3]
            return r

        x0, info, ok, msg = fsolve(residual, guess, full_output=True, xtol=1e-13)
        assert ok == 1, msg
        return x0

    def simulate(self, t_out):
        return integrate_between_switches(self.rhs, self.output, self.steady_start(), self.p, t_out)


def integrate_between_switches(rhs, output, x0, p, t_out):
    """Output at ``t_out`` of ``x' = rhs(t, x)`` from ``x0``, integrating each interval
    between the source's switching times (``src.t_step``, ``src.t_return``, each moved by a
    transport delay ``src.t_delay``) apart."""
    late = p.get("src.t_delay", 0.0)
    cuts = sorted({0.0, p["src.t_step"] + late, p["src.t_return"] + late, float(t_out[-1])})
    cuts = [c for c in cuts if c <= t_out[-1]]
    x = x0
    y = np.full(len(t_out), np.nan)
    for a, b in zip(cuts[:-1], cuts[1:]):
        mask = (t_out >= a) & (t_out < b) if b < t_out[-1] else (t_out >= a) & (t_out <= b)
        # max_step keeps the integrator from stepping over the smooth corners
        sol = solve_ivp(lambda t, s: rhs(t if t < b else np.nextafter(b, a), s), (a, b), x,
                        method="LSODA", rtol=1e-10, atol=1e-12, dense_output=True, max_step=0.05)
        if mask.any():
            states = sol.sol(t_out[mask])
            y[mask] = [output(t, states[:, k]) for k, t in enumerate(t_out[mask])]
        x = sol.y[:, -1]
    return y
