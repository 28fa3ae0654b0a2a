"""HYGOV, HYGOVD, GGOV1 and GAST records against their own block diagrams, linearised by hand.

Why this test exists: the TGOV1 and IEEEG1 records the project writes are replayed in
an outside grid simulator (ANDES, tests/test_andes_replay.py). For HYGOV and GGOV1 there
is no trustworthy independent simulator here: ANDES's HYGOV departs from PSS/E's (its
gate integrator lacks the 1/(r Tr) gain) and ANDES 2.0 has no GGOV1. So each record is
obtained the way a user obtains it (a short calibration of a synthetic staged test,
tests/test_delivery.py's ``_calibrated``; ``rc.export`` to ``.dyr``; ``read_record``),
played on the project's staged-test bench (fmus["StagedTest<MODEL>"]) with a frequency
step small enough that no limit, rate limit, gate or low-value-gate switch acts, and the
bench's change of mechanical power is compared with what the published block diagrams
(PSS/E Model Library; IEEE PES-TR1 2013, sec. 3.3 GGOV1 and sec. 4.1 HYGOV) give,
linearised at the operating point. The linearisations below are this file's own, from
the diagrams: not from the Modelica source and not from tests/reference_standard.py
(a nonlinear integration of the same diagrams: a different check).

Conventions: a step of df Hz at f_nom is a speed step SPEED = w - 1 = df / f_nom (PSS/E's
input); the bench's input is dw = w_ref - w = -SPEED. s is the Laplace variable; a
leading delta is a change from the operating point (p_ref 0.6 pu).

What is derived
---------------
HYGOV (speed error nref - SPEED - R c -> 1/(1 + s Tf) -> e; PI (1 + s Tr)/(r Tr s) -> desired
gate c; gate g = c/(1 + s Tg); water column TW dq/dt = 1 - h, h = (q/g)^2; power
Pm = At h (q - qNL) - Dturb SPEED g). At rest q = g = q0 = p_ref/At + qNL, h = 1.
Linearised: dc/ddw = (1 + s Tr) / (r Tr s (1 + s Tf) + R (1 + s Tr)); the head
dh = (2/q0)(dq - dg) with TW s dq = -dh gives dq = dg / (1 + s TW q0/2), and
dPm = At (q0 - qNL) dh + At dq + Dturb q0 ddw, so the turbine is the water-hammer
transfer function At (1 - s TW (q0 - qNL)) / (1 + s TW q0 / 2) from the gate:
  dPm/ddw = At (1 - s TW (q0 - qNL)) (1 + s Tr)
            / [(r Tr s (1 + s Tf) + R (1 + s Tr)) (1 + s Tg) (1 + s TW q0 / 2)] + Dturb q0.
Steady state: dPm = (At / R + Dturb q0) ddw (the permanent droop on the gate).

GGOV1 (speed error Pref - R F - SPEED, PID C = Kpgov + Kigov/s + Kdgov s/(1 + s Tdgov),
the low-value gate passing the governor, actuator A = 1/(1 + s Tact), fuel flow
wf = v (1 + SPEED) with Flag 1 (v with Flag 0), turbine T = Kturb (1 + s Tc)/(1 + s Tb)
on wf - Wfnl, Pm less Dm SPEED; v0 = p_ref/Kturb + Wfnl). Linearised, with
dwf = dv + Flag v0 SPEED:
  Rselect 1 (F = Pelec/(1 + s Tpelec) = P dPm, Pelec = Pm on the staged test's stiff grid):
    dPm/SPEED = (-T A C + Flag v0 T - Dm) / (1 + R P T A C);   steady: dPm = -SPEED / R;
  Rselect -1 (F = valve stroke v): dv/SPEED = -A C / (1 + R A C),
    dPm/SPEED = -T A C / (1 + R A C) + Flag v0 T - Dm;   steady: dPm = (Kturb (Flag v0 - 1/R) - Dm) SPEED;
  Rselect 0 (isochronous): dPm/SPEED = -T A C + Flag v0 T - Dm. On a staged test the speed
    error -SPEED is held, so the integrator never returns the power: no steady state, but
    a ramp asymptote dPm -> SPEED (a t + b), a = -Kturb Kigov,
    b = -Kturb (Kpgov + Kigov (Tc - Tb - Tact)) + Flag v0 Kturb - Dm (t from the step).

GAST (demand P_ref - SPEED / R and the temperature limit AT + KT (AT - x3) into a low-value
gate passing the demand; fuel valve 1/(1 + s T1); fuel flow 1/(1 + s T2) is the power, less
Dturb SPEED). Linearised, the gate passing the demand:
  dPm/ddw = (1/R) / ((1 + s T1)(1 + s T2)) + Dturb;   steady: dPm = (1/R + Dturb) ddw.
GAST is also replayed in ANDES (tests/test_andes_replay.py); this checks the record against
the diagram itself.

HYGOVD: HYGOV with the speed deadband of half-width db before the speed error and the
damping, the no-step form: a step ddw beyond the band acts as ddw - db sign(ddw), so the
response is HYGOV's to the reduced step. The record is written by the project's writer
(HYGOVD: HYGOV's fields, dbH, dbL, Trate), read back, and played; ANDES's HYGOV (and its
HYGOVDB) lacks PSS/E's gain, so the diagram is the check.

Tolerances
----------
The bench's response is pm(step) - pm(rest): the same record and operating point
simulated without the step. (GGOV1's bench drifts at rest, by up to 3e-7 pu in these
windows: its smooth Vmin/Vmax clamp holds the gate's output 7e-10 pu below the
governor's, which the back-calculation gain K_track integrates. Asserted below
REST_TOL = 0.1 % of the response.)
* Dynamics: every sample within DYNAMICS_TOL = 1 % of the derived response's peak change.
  What the linearisation and the bench leave between them: the second-order terms of the
  0.002 Hz step (a priori at most |dx|/x0, about 0.1 %: gate and valve move about 1e-3 pu
  from 0.6; measured 2e-5 to 5e-5, scaling with the step: HYGOV's head, GGOV1's Flag
  product v SPEED); the smooth limits' slope (differs from one by eps_v^2/(4 d^2) <= 6e-4
  at the distances d >= 20 eps_v asserted below, the soft gate's weight by e^-20); the
  solver (the default exponential runner, 1e-7 pu just after the step, 7e-5 of the peak;
  CVODE at its default tolerance, runner "compiled", 3e-3). 1 % stays above all of them
  with either runner; measured with the default runner: at most 7e-5 of the peak.
* Steady state: within STEADY_TOL = 0.5 % of the derived value (for Rselect 0: the ramp's
  slope, and its offset b), at the end of a window of SETTLE = 12 time constants of the
  derived transfer function's slowest pole (its mode left at e^-12 = 6e-6). The same
  terms, without the solver's transient error; measured at most 2e-4.
What these catch (checked by hand, perturbing one derived quantity): R x 1.1 (10 %);
the Flag term of the other flag (2 %, 7 % of the ramp's offset for Rselect 0); Kpgov,
Kigov, Kturb or Tb x 1.1 (1.5 to 9 %); HYGOV's water column taken as the textbook
At (1 - s TW)/(1 + s TW/2), without the operating point's flow (8 %); r or Tr x 1.1 (3 %),
TW x 1.1 (1.1 %, just); the input's sign. Not always caught: a 10 % error in a small time
constant (HYGOV's Tf, Tg; GGOV1's Tact, Tpelec) moves the response by 0.1 to 2 % of its
peak, caught only where that is above 1 %.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from rapid_cosim.exchange import read_record
from rapid_cosim.simulator import Simulator

P_REF = 0.6  # pu: well inside every gate/valve range and far below GGOV1's load limit (Ldref 1.0)
F_NOM = 50.0  # Hz
DF = -0.002  # Hz: a small frequency drop, SPEED = -4e-5 pu
T_STEP = 1.0  # s
DT = 0.02  # s: the output grid (the fastest derived pole here is about 23/s)
SETTLE = 12.0  # time constants of the slowest derived pole in the window
DYNAMICS_TOL = 0.01  # of the derived response's peak change
STEADY_TOL = 0.005  # of the derived steady state (slope and offset of the ramp for Rselect 0)
REST_TOL = 0.001  # the bench's drift at rest, of the derived response's peak change

mul, add = np.polymul, np.polyadd  # polynomials with the highest power first, as scipy.signal


def _trim(p: np.ndarray) -> np.ndarray:
    """A polynomial without its leading (exactly or numerically) zero coefficients."""
    p = np.atleast_1d(np.asarray(p, float))
    big = np.max(np.abs(p))
    keep = np.flatnonzero(np.abs(p) > 1e-12 * big) if big > 0 else np.array([p.size - 1])
    return p[keep[0]:]


# ---------------------------------------------------------------------- derivations
def hygov_linear(v: dict, p_ref: float) -> tuple[np.ndarray, np.ndarray]:
    """dPm/ddw of the HYGOV diagram linearised at p_ref (see the module docstring)."""
    q0 = p_ref / v["At"] + v["qNL"]
    governor_num = np.array([v["Tr"], 1.0])  # (1 + s Tr)
    governor_den = add(mul([v["r"] * v["Tr"], 0.0], [v["Tf"], 1.0]), v["R"] * np.array([v["Tr"], 1.0]))
    gate = np.array([v["Tg"], 1.0])
    turbine_num = v["At"] * np.array([-v["TW"] * (q0 - v["qNL"]), 1.0])  # the water-hammer zero
    turbine_den = np.array([v["TW"] * q0 / 2.0, 1.0])
    den = mul(mul(governor_den, gate), turbine_den)
    num = add(mul(governor_num, turbine_num), v["Dturb"] * q0 * den)  # + Dturb g0 ddw, direct
    return _trim(num), _trim(den)


def hygov_steady(v: dict, p_ref: float) -> float:
    """dPm/ddw at steady state: the gate moves 1/R per unit speed, the head returns to 1."""
    q0 = p_ref / v["At"] + v["qNL"]
    return v["At"] / v["R"] + v["Dturb"] * q0


def gast_linear(v: dict) -> tuple[np.ndarray, np.ndarray]:
    """dPm/ddw of the GAST diagram, the low-value gate passing the demand."""
    den = mul([v["T1"], 1.0], [v["T2"], 1.0])
    return _trim(add([1.0 / v["R"]], v["Dt"] * den)), _trim(den)


def ggov1_linear(v: dict, p_ref: float) -> tuple[np.ndarray, np.ndarray]:
    """dPm/SPEED of the GGOV1 diagram linearised at p_ref, the low-value gate passing the
    governor's output (see the module docstring)."""
    v0 = p_ref / v["Kturb"] + v["Wfnl"]
    # C = Nc / Dc = Kpgov + Kigov / s + Kdgov s / (1 + s Tdgov)
    nc = add(mul([v["Kpgov"], v["Kigov"]], [v["Tdgov"], 1.0]), [v["Kdgov"], 0.0, 0.0])
    dc = mul([1.0, 0.0], [v["Tdgov"], 1.0])
    nt, dt = v["Kturb"] * np.array([v["Tc"], 1.0]), np.array([v["Tb"], 1.0])  # T = Nt / Dt
    da = np.array([v["Tact"], 1.0])  # A = 1 / Da
    dp = np.array([v["Tpelec"], 1.0])  # P = 1 / Dp
    direct = add(v["Flag"] * v0 * nt, -v["Dm"] * dt)  # (Flag v0 T - Dm) Dt
    if v["Rselect"] == 1:
        num = mul(add(-mul(nt, nc), mul(direct, mul(da, dc))), dp)
        den = add(mul(mul(dt, da), mul(dc, dp)), v["R"] * mul(nt, nc))
    elif v["Rselect"] == -1:
        loop = add(mul(da, dc), v["R"] * nc)  # Da Dc (1 + R A C)
        num = add(-mul(nt, nc), mul(direct, loop))
        den = mul(dt, loop)
    else:
        num = add(-mul(nt, nc), mul(direct, mul(da, dc)))
        den = mul(dt, mul(da, dc))
    return _trim(num), _trim(den)


def ggov1_steady(v: dict, p_ref: float) -> tuple[float, float]:
    """Rselect +-1: (dPm/SPEED at steady state, 0). Rselect 0: the ramp asymptote's
    (a, b), dPm -> SPEED (a t + b)."""
    v0 = p_ref / v["Kturb"] + v["Wfnl"]
    if v["Rselect"] == 1:  # the integrator holds R dPelec = -SPEED, Pelec = Pm
        return -1.0 / v["R"], 0.0
    if v["Rselect"] == -1:  # the integrator holds R dv = -SPEED
        return v["Kturb"] * (v["Flag"] * v0 - 1.0 / v["R"]) - v["Dm"], 0.0
    return (-v["Kturb"] * v["Kigov"],
            -v["Kturb"] * (v["Kpgov"] + v["Kigov"] * (v["Tc"] - v["Tb"] - v["Tact"])) + v["Flag"] * v0 * v["Kturb"]
            - v["Dm"])


# ---------------------------------------------------------------------- the bench
def _record(fmus, tmp_path, case: str, model: str):
    import rapid_cosim as rc
    from test_delivery import _calibrated

    fit, _ = _calibrated(fmus, tmp_path, case)
    rc.export(fit.archive, tmp_path / "unit.dyr")
    record = read_record(tmp_path / "unit.dyr")
    assert record.model == model
    return record


def _window(den: np.ndarray) -> float:
    """SETTLE time constants of the slowest pole (integrators left out: Rselect 0's ramp)."""
    rates = [-p.real for p in np.roots(den) if abs(p) > 1e-9]
    assert all(r > 0 for r in rates), f"the derived system is unstable: poles {np.roots(den)}"
    return SETTLE / min(rates)


def _play(sim: Simulator, values: dict, window: float):
    """The record played on the staged test: time, pm(step) - pm(rest), and the rest run's
    pm - p_ref."""
    t = T_STEP + DT * np.arange(-round(T_STEP / DT), math.ceil(window / DT) + 1)  # t_step on the grid
    params = {f"gov.{k}": x for k, x in values.items()} | {
        "gov.p_ref": P_REF, "src.f_nom": F_NOM, "src.t_step": T_STEP, "src.t_return": 1e9}
    step = sim.simulate({**params, "src.df": DF}, output_times=t, outputs=["pm"])["pm"]
    rest = sim.simulate({**params, "src.df": 0.0}, output_times=t, outputs=["pm"])["pm"]
    return t, step - rest, rest - P_REF


def _derived(num, den, t: np.ndarray, size: float) -> np.ndarray:
    """The step response of num/den to a step of ``size`` at T_STEP, on the grid t."""
    after = t >= T_STEP
    _, y, _ = signal.lsim((num, den), U=np.ones(after.sum()), T=t[after] - T_STEP)
    out = np.zeros_like(t)
    out[after] = size * y
    return out


def _check_dynamics(t, bench, derived, rest):
    peak = np.max(np.abs(derived))
    worst = np.max(np.abs(bench - derived))
    assert np.max(np.abs(rest)) <= REST_TOL * peak, f"not at rest: drift {np.max(np.abs(rest)):.2e} pu"
    assert np.max(np.abs(bench[t < T_STEP])) <= 1e-12  # nothing before the step
    assert worst <= DYNAMICS_TOL * peak, (
        f"bench vs derived step response: {worst:.3e} pu at t = {t[np.argmax(np.abs(bench - derived))]:.2f} s, "
        f"{worst / peak:.2%} of the peak {peak:.3e} pu (tolerance {DYNAMICS_TOL:.0%})")
    return worst / peak


def _margin(name: str, distance: float, eps: float) -> None:
    """A smooth limit or the soft low-value gate at ``distance`` from acting: its slope
    differs from one by eps^2 / (4 d^2) (the gate's weight by exp(-d / eps)); 20 eps keeps
    both below 1e-3 (the gate's, 2e-9)."""
    assert distance >= 20 * eps, f"{name}: {distance:.3g} from acting, less than 20 eps_v ({20 * eps:g})"


# ---------------------------------------------------------------------- HYGOV
def test_hygov_record_follows_its_linearised_block_diagram(fmus, tmp_path):
    record = _record(fmus, tmp_path, "HYGOV", "HYGOV")
    v = record.values
    sim = Simulator(fmus["StagedTestHYGOV"])
    eps = sim.parameters["gov.eps_v"].start  # no field carries it: the bench's default
    ddw = -DF / F_NOM  # the bench's input, w_ref - w
    q0 = P_REF / v["At"] + v["qNL"]
    # no limit near: the gate's range around q0 + ddw / R, the velocity limit above the
    # integral part's speed (at most |ddw| / (r Tr), the filtered error being below |ddw|)
    _margin("GMAX", v["GMAX"] - (q0 + abs(ddw) / v["R"]), eps)
    _margin("GMIN", q0 - abs(ddw) / v["R"] - v["GMIN"], eps)
    _margin("VELM", v["VELM"] - abs(ddw) / (v["r"] * v["Tr"]), eps)

    num, den = hygov_linear(v, P_REF)
    steady = hygov_steady(v, P_REF)
    assert np.polyval(num, 0) / np.polyval(den, 0) == pytest.approx(steady, rel=1e-12)  # the two derivations agree
    t, bench, rest = _play(sim, v, _window(den))
    derived = _derived(num, den, t, ddw)

    _check_dynamics(t, bench, derived, rest)
    assert bench[-1] == pytest.approx(steady * ddw, rel=STEADY_TOL), "steady state (At/R + Dturb q0) ddw"
    # the water hammer: opening the gate first drops the head, the power dips below its rest
    assert bench.min() < 0 < bench[-1]


# ---------------------------------------------------------------------- GGOV1
@pytest.mark.parametrize("flag", (1, 0))
@pytest.mark.parametrize("rselect", (1, -1, 0))
def test_ggov1_record_follows_its_linearised_block_diagram(fmus, tmp_path, rselect, flag):
    record = _record(fmus, tmp_path, f"GGOV1, Rselect {rselect}, Flag {flag}", "GGOV1")
    v = record.values
    assert (v["Rselect"], v["Flag"]) == (rselect, flag)
    # what the linearisation leaves out must be off: no deadband, no power controller; Dm
    # enters as -Dm SPEED only for Dm >= 0 (the diagram's Dm < 0 acts on the fuel limit)
    assert v["db"] == 0.0 and v["Kimw"] == 0.0 and v["Dm"] >= 0.0
    sim = Simulator(fmus["StagedTestGGOV1"])
    eps = sim.parameters["gov.eps_v"].start  # no field carries these: the bench's defaults
    delt = sim.parameters["gov.DELT"].start
    speed = DF / F_NOM  # SPEED = w - 1; the bench's input dw is its negative

    num, den = ggov1_linear(v, P_REF)
    window = _window(den)
    a, b = ggov1_steady(v, P_REF)
    if rselect == 0:  # the derived ramp: s G(s) = num / den1 with den = s den1, G/s ~ a/s^2 + b/s
        den1 = np.polydiv(den, [1.0, 0.0])[0]
        assert np.polyval(num, 0) / np.polyval(den1, 0) == pytest.approx(a, rel=1e-12)
        slope_b = (np.polyval(np.polyder(num), 0) * np.polyval(den1, 0)
                   - np.polyval(num, 0) * np.polyval(np.polyder(den1), 0)) / np.polyval(den1, 0) ** 2
        assert slope_b == pytest.approx(b, rel=1e-9)
    else:
        assert np.polyval(num, 0) / np.polyval(den, 0) == pytest.approx(a, rel=1e-12)
    t, bench, rest = _play(sim, v, window)
    derived = _derived(num, den, t, speed)

    # no limiter near the gate, no limit near the valve, over the whole response:
    v0 = P_REF / v["Kturb"] + v["Wfnl"]
    valve = np.max(np.abs(derived)) / v["Kturb"] + v["Kpgov"] * abs(speed)  # valve move + the proportional jump
    # (its output sits Kpload x (its reference less the fuel flow) above the governor's; the
    # fuel flow it reads moves by at most the valve's move)
    _margin("load limiter", v["Kpload"] * ((v["Ldref"] - P_REF) / v["Kturb"] - valve), eps)
    # the acceleration limiter sits Ka DELT aset above the gate's output, which lags the
    # governor's by DELT (its proportional jump); a frequency drop only raises it further
    _margin("acceleration limiter", v["Ka"] * delt * v["aset"] - v["Kpgov"] * abs(speed), eps)
    _margin("Vmax", v["Vmax"] - v0 - valve, eps)
    _margin("Vmin", v0 - valve - v["Vmin"], eps)
    _margin("Ropen", v["Ropen"] - valve / v["Tact"], eps)
    _margin("Rclose", -v["Rclose"] - valve / v["Tact"], eps)
    _margin("maxerr", v["maxerr"] - abs(speed), eps)
    _margin("minerr", -v["minerr"] - abs(speed), eps)

    _check_dynamics(t, bench, derived, rest)
    if rselect == 0:  # the ramp's slope and offset over the window's last 2 s
        last = t >= t[-1] - 2.0
        slope, offset = np.polyfit(t[last] - T_STEP, bench[last], 1)
        assert slope == pytest.approx(a * speed, rel=STEADY_TOL), "ramp slope -Kturb Kigov SPEED"
        assert offset == pytest.approx(b * speed, rel=STEADY_TOL), "ramp offset b SPEED"
    else:
        assert bench[-1] == pytest.approx(a * speed, rel=STEADY_TOL), (
            "steady state: -SPEED / R (Rselect 1), (Kturb (Flag v0 - 1/R) - Dm) SPEED (Rselect -1)")


# ---------------------------------------------------------------------- HYGOVD
def test_hygovd_record_acts_on_the_deviation_beyond_its_band(fmus, tmp_path):
    from rapid_cosim.exchange import psse_dyr

    db = 1.5e-5  # pu of speed: the 0.002 Hz step (4e-5 pu) leaves it by 2.5e-5
    values = {"R": 0.05, "r": 0.3, "Tr": 5.0, "Tf": 0.05, "Tg": 0.5, "VELM": 0.2, "GMAX": 1.0, "GMIN": 0.0,
              "TW": 1.2, "At": 1.2, "Dturb": 0.3, "qNL": 0.08, "db": db}
    psse_dyr.write_record(tmp_path / "unit.dyr", "HYGOV", values, bus=3)
    record = read_record(tmp_path / "unit.dyr")
    assert (record.model, record.block, record.values["db"]) == ("HYGOVD", "HYGOV", db)
    sim = Simulator(fmus["StagedTestHYGOV"])
    ddw = -DF / F_NOM
    num, den = hygov_linear(record.values, P_REF)
    t, bench, rest = _play(sim, record.values, _window(den))
    derived = _derived(num, den, t, ddw - db)  # the step less the band
    _check_dynamics(t, bench, derived, rest)
    assert bench[-1] == pytest.approx(hygov_steady(record.values, P_REF) * (ddw - db), rel=STEADY_TOL)
    plain = {k: v for k, v in record.values.items() if k != "db"}
    _, without, _ = _play(sim, plain, _window(den))
    assert without[-1] / bench[-1] == pytest.approx(ddw / (ddw - db), rel=STEADY_TOL)  # the band's share


# ---------------------------------------------------------------------- GAST
def test_gast_record_follows_its_linearised_block_diagram(fmus, tmp_path):
    record = _record(fmus, tmp_path, "GAST", "GAST")
    v = record.values
    sim = Simulator(fmus["StagedTestGAST"])
    eps = sim.parameters["gov.eps_v"].start
    ddw = -DF / F_NOM
    move = abs(ddw) / v["R"]
    _margin("temperature limit", v["AT"] + v["KT"] * (v["AT"] - P_REF - move) - (P_REF + move), eps)
    _margin("VMAX", v["VMAX"] - P_REF - move, eps)
    _margin("VMIN", P_REF - move - v["VMIN"], eps)
    num, den = gast_linear(v)
    t, bench, rest = _play(sim, v, _window(den))
    derived = _derived(num, den, t, ddw)
    _check_dynamics(t, bench, derived, rest)
    assert bench[-1] == pytest.approx((1.0 / v["R"] + v["Dt"]) * ddw, rel=STEADY_TOL), "steady state (1/R + Dt) ddw"
