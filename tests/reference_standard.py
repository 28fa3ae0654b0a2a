"""Independent reference for the standard governors (TGOV1, IEEEG1, GGOV1, HYGOV, GAST): their
block diagrams in IEEE PES-TR1 (2013) and the PSS/E model library written out as numpy
right-hand sides and integrated with scipy between the source's switching times.

Limits use the smooth forms the models' documentation states (the non-windup gate and
the rate limits rounded over eps, GGOV1's low-value gate as a soft minimum through
scipy's logsumexp, GAST's the same way); everything else is the textbook diagram, the
speed deadbands (TGOV1D, IEEEG1D, HYGOVD: the no-step form) exact clamps. The input is
the staged test's speed deviation dw = w_ref - w = -df / f_nom.
"""

from __future__ import annotations

import numpy as np
from reference_models import integrate_between_switches
from scipy.special import logsumexp

SOURCE = {"src.df": -0.2, "src.f_nom": 50.0, "src.t_step": 10.0, "src.t_return": 1e9}
DEFAULTS = {
    "TGOV1": {"R": 0.05, "T1": 0.5, "VMAX": 1.0, "VMIN": 0.0, "T2": 2.5, "T3": 7.5, "Dt": 0.0, "db": 0.0,
              "p_ref": 0.6, "eps_v": 1e-4, "K_lim": 100.0},
    "HYGOV": {"R": 0.05, "r": 0.3, "Tr": 5.0, "Tf": 0.05, "Tg": 0.5, "VELM": 0.2, "GMAX": 1.0, "GMIN": 0.0,
              "TW": 1.0, "At": 1.2, "Dturb": 0.5, "qNL": 0.08, "db": 0.0, "p_ref": 0.6, "eps_v": 1e-4,
              "K_lim": 100.0},
    "IEEEG1": {"K": 20.0, "T1": 0.001, "T2": 0.0, "T3": 0.1, "Uo": 1.0, "Uc": -1.0, "PMAX": 1.0, "PMIN": 0.0,
               "T4": 0.3, "K1": 0.2, "T5": 7.0, "K3": 0.3, "K3_rest": 0.0, "T6": 0.6, "K5": 0.5, "T7": 0.05,
               "K7": 0.0, "db": 0.0, "p_ref": 0.6, "eps_v": 1e-4, "K_lim": 100.0},
    "GAST": {"R": 0.05, "T1": 0.4, "T2": 0.1, "T3": 3.0, "AT": 1.0, "KT": 2.0, "VMAX": 1.0, "VMIN": 0.0, "Dt": 0.0,
             "p_ref": 0.6, "eps_v": 1e-4, "K_lim": 100.0},
    "GGOV1": {"R": 0.04, "Rselect": 1.0, "Tpelec": 1.0, "maxerr": 0.05, "minerr": -0.05, "Kpgov": 10.0,
              "Kigov": 2.0, "Kdgov": 0.0, "Tdgov": 1.0, "Vmax": 1.0, "Vmin": 0.15, "Tact": 0.5, "Kturb": 1.5,
              "Wfnl": 0.2, "Tb": 0.5, "Tc": 0.0, "Flag": 1.0, "Tfload": 3.0, "Kpload": 2.0, "Kiload": 0.67,
              "Ldref": 1.0, "Dm": 0.0, "Ropen": 0.1, "Rclose": -0.1, "Kimw": 0.0, "aset": 0.1, "Ka": 10.0,
              "Ta": 0.1, "db": 0.0, "Tsa": 4.0, "Tsb": 5.0, "DELT": 0.005, "p_ref": 0.6, "eps_v": 1e-4,
              "K_lim": 100.0, "K_track": 10.0},
}


def sp(z, eps):
    """max(z, 0) rounded over eps."""
    return 0.5 * (z + np.sqrt(z * z + eps * eps))


def non_windup(d, x, lo, hi, p):
    """An integrator's speed d, capped near a limit: min(d, K_lim (hi - x)) and
    max(., -K_lim (x - lo)), rounded over eps_v, exactly d = 0 at rest."""
    e, k = p["eps_v"], p["K_lim"]
    return (d - (sp(d - k * (hi - x), e) - sp(-k * (hi - x), e))
            + (sp(-d - k * (x - lo), e) - sp(-k * (x - lo), e)))


def deadband(dw, db):
    """The no-step deadband: dw less its clamp to [-db, db] (0 inside the band)."""
    return dw - np.clip(dw, -db, db)


def rate_limit(v, lo, hi, eps):
    """v clamped to [lo, hi] (lo < 0 < hi), rounded over eps, exact at v = 0."""
    return v - (sp(v - hi, eps) - sp(-hi, eps)) + (sp(lo - v, eps) - sp(lo, eps))


class Standard:
    def __init__(self, model: str, params: dict):
        self.model = model
        self.p = {**SOURCE, **DEFAULTS[model], **{k.removeprefix("gov."): v for k, v in params.items()}}

    def dw(self, t):
        p = self.p
        return -p["src.df"] / p["src.f_nom"] if p["src.t_step"] <= t < p["src.t_return"] else 0.0

    # ------------------------------------------------------------------ TGOV1
    def _tgov1(self, dw, x):
        p = self.p
        dw = deadband(dw, p["db"])
        x1, x2 = x
        d = (p["p_ref"] + dw / p["R"] - x1) / p["T1"]
        dx = [non_windup(d, x1, p["VMIN"], p["VMAX"], p), (x1 - x2) / p["T3"]]
        pm = x2 + p["T2"] / p["T3"] * (x1 - x2) + p["Dt"] * dw
        return dx, pm

    # ------------------------------------------------------------------ HYGOV
    def _hygov(self, dw, x):
        p = self.p
        dw = deadband(dw, p["db"])
        e, xi, g, q = x
        q0 = p["p_ref"] / p["At"] + p["qNL"]
        c = xi + e / p["r"]
        de = (p["R"] * q0 + dw - p["R"] * c - e) / p["Tf"]
        vl = rate_limit(e / (p["r"] * p["Tr"]), -p["VELM"], p["VELM"], p["eps_v"])
        h = (q / g) ** 2
        dx = [de, non_windup(vl, xi, p["GMIN"], p["GMAX"], p), (c - g) / p["Tg"], (1 - h) / p["TW"]]
        return dx, p["At"] * h * (q - p["qNL"]) + p["Dturb"] * dw * g

    # ------------------------------------------------------------------ IEEEG1
    def _ieeeg1_k3(self) -> float:
        """The second stage's fraction: with K3_rest = 1, the rest of the shaft (the stages sum to one)."""
        p = self.p
        return 1 - p["K1"] - p["K5"] - p["K7"] if p["K3_rest"] == 1 else p["K3"]

    def _ieeeg1(self, dw, x):
        p = self.p
        dw = deadband(dw, p["db"])
        xl, gv, x4, x5, x6, x7 = x
        k3 = self._ieeeg1_k3()
        gv0 = p["p_ref"] / (p["K1"] + k3 + p["K5"] + p["K7"])
        ysp = p["K"] * (xl + p["T2"] / p["T1"] * (dw - xl))
        vl = rate_limit((gv0 + ysp - gv) / p["T3"], p["Uc"], p["Uo"], p["eps_v"])
        dx = [(dw - xl) / p["T1"], non_windup(vl, gv, p["PMIN"], p["PMAX"], p), (gv - x4) / p["T4"],
              (x4 - x5) / p["T5"], (x5 - x6) / p["T6"], (x6 - x7) / p["T7"]]
        return dx, p["K1"] * x4 + k3 * x5 + p["K5"] * x6 + p["K7"] * x7

    # ------------------------------------------------------------------ GGOV1
    def _ggov1_feedback(self, pef, v):
        p = self.p
        return {1.0: pef, -1.0: v}.get(p["Rselect"], 0.0)

    def _ggov1(self, dw, x):
        p = self.p
        e = p["eps_v"]
        pef, xmw, xg, xd, xf, xs, xl, xa, z, v, xt = x
        v0 = p["p_ref"] / p["Kturb"] + p["Wfnl"]
        spd = -dw if p["db"] == 0 else -dw - np.clip(-dw, -p["db"], p["db"])  # db = 0 in every case
        wf = v * (1 + spd if p["Flag"] == 1 else 1.0)
        u_t = p["Kturb"] * (wf - p["Wfnl"])
        pm = xt + p["Tc"] / p["Tb"] * (u_t - xt) - p["Dm"] * spd
        pref = p["R"] * self._ggov1_feedback(p["p_ref"], v0)
        err = pref + xmw - p["R"] * self._ggov1_feedback(pef, v) - spd
        errl = err - sp(err - p["maxerr"], e) + sp(p["minerr"] - err, e)
        fsrn = p["Kpgov"] * errl + xg + p["Kdgov"] * (errl - xd) / p["Tdgov"]
        texm = xs + p["Tsa"] / p["Tsb"] * (xf - xs)
        margin = p["Ldref"] / p["Kturb"] + p["Wfnl"] - texm
        fsrt = p["Kpload"] * margin + xl
        acc = (spd - xa) / p["Ta"]
        fsra = z + p["Ka"] * p["DELT"] * (p["aset"] - acc)
        fsr = -e * logsumexp([-fsrn / e, -fsrt / e, -fsra / e])
        fsrl = fsr - sp(fsr - p["Vmax"], e) + sp(p["Vmin"] - fsr, e)
        dl = p["Kiload"] * margin
        dx = [(pm - pef) / p["Tpelec"], p["Kimw"] * (p["p_ref"] - pef),
              p["Kigov"] * errl + p["K_track"] * (fsrl - fsrn), (errl - xd) / p["Tdgov"],
              (wf - xf) / p["Tfload"], (xf - xs) / p["Tsb"],
              dl - sp(dl - sp(p["K_lim"] * (fsrl - xl), e), e),  # min(dl, max(K_lim (fsrl - xl), 0))
              acc, (fsrl - z) / p["DELT"], rate_limit((fsrl - v) / p["Tact"], p["Rclose"], p["Ropen"], e),
              (u_t - xt) / p["Tb"]]
        return dx, pm

    # ------------------------------------------------------------------ GAST
    def _gast(self, dw, x):
        p = self.p
        x1, x2, x3 = x
        demand = p["p_ref"] + dw / p["R"]
        limit = p["AT"] + p["KT"] * (p["AT"] - x3)
        gate = -p["eps_v"] * logsumexp([-demand / p["eps_v"], -limit / p["eps_v"]])  # the soft low-value gate
        dx = [non_windup((gate - x1) / p["T1"], x1, p["VMIN"], p["VMAX"], p), (x1 - x2) / p["T2"], (x2 - x3) / p["T3"]]
        return dx, x2 + p["Dt"] * dw

    def _f(self, t, x):
        return {"TGOV1": self._tgov1, "HYGOV": self._hygov, "IEEEG1": self._ieeeg1,
                "GGOV1": self._ggov1, "GAST": self._gast}[self.model](self.dw(t), x)

    def start(self):
        """The steady state at the dispatch, from the diagrams (dw = 0)."""
        p = self.p
        if self.model in ("TGOV1", "GAST"):
            x1 = min(max(p["p_ref"], p["VMIN"]), p["VMAX"])
            return np.array([x1, x1] if self.model == "TGOV1" else [x1, x1, x1])
        if self.model == "HYGOV":
            q0 = p["p_ref"] / p["At"] + p["qNL"]
            return np.array([0.0, q0, q0, q0])
        if self.model == "GGOV1":
            v0 = p["p_ref"] / p["Kturb"] + p["Wfnl"]
            return np.array([p["p_ref"], 0.0, v0, 0.0, v0, v0, v0, 0.0, v0, v0, p["p_ref"]])
        gv0 = p["p_ref"] / (p["K1"] + self._ieeeg1_k3() + p["K5"] + p["K7"])
        return np.array([0.0, gv0, gv0, gv0, gv0, gv0])

    def simulate(self, t_out):
        return integrate_between_switches(lambda t, x: np.asarray(self._f(t, x)[0]), lambda t, x: self._f(t, x)[1],
                                          self.start(), self.p, t_out)
