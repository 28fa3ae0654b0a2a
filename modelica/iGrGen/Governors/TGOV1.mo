within iGrGen.Governors;
block TGOV1 "Steam turbine-governor TGOV1 (PSS/E; IEEE PES-TR1 2013, sec. 2.1)"
  parameter Real R(unit="1", min=0.001, max=1) = 0.05 "permanent droop (pu)";
  parameter Real T1(unit="s", min=0.001, max=100) = 0.5 "steam bowl / governor time constant";
  parameter Real VMAX(unit="1", min=0, max=2) = 1.0 "maximum valve position (pu)";
  parameter Real VMIN(unit="1", min=0, max=2) = 0.0 "minimum valve position (pu)";
  parameter Real T2(unit="s", min=0, max=100) = 2.5 "numerator (lead) time constant of the reheater";
  parameter Real T3(unit="s", min=0.001, max=100) = 7.5 "reheater time constant";
  parameter Real Dt(unit="1", min=0, max=10) = 0.0 "turbine damping coefficient (pu)";
  parameter Real p_ref(unit="1", min=0, max=2) = 0.6 "power reference, the dispatch (pu)";
  parameter Real eps_v(unit="1/s", min=1e-9, max=1) = 1e-4 "sharpness: rounding of the non-windup gate in valve speed (pu/s)";
  parameter Real K_lim(unit="1/s", min=1, max=1e4) = 100 "sharpness of the non-windup limit: a state at a limit is held within (its speed) / K_lim of it";
  Interfaces.RealInput dw "speed deviation w_ref - w (pu): PSS/E's -SPEED";
  Interfaces.RealOutput pm "mechanical power (pu)";
  Real u "valve command before the lag (pu)";
  Real d "free valve speed (pu/s)";
  Real x1 "valve position, the lag state (pu)";
  Real x2 "reheater state (pu)";
initial equation
  x1 = min(max(p_ref, VMIN), VMAX);
  x2 = x1;
equation
  u = p_ref + dw.signal / R;
  d = (u - x1) / T1;
  // Non-windup lag: the valve stops at a limit and leaves it as soon as the command turns
  // back. The speed is min(d, K_lim (VMAX - x1)) and max(., -K_lim (x1 - VMIN)), rounded
  // with sp(z) = (z + sqrt(z^2 + eps_v^2)) / 2 and corrected to vanish at d = 0.
  der(x1) = d - (0.5 * (d - K_lim * (VMAX - x1) + sqrt((d - K_lim * (VMAX - x1)) ^ 2 + eps_v ^ 2))
      - 0.5 * (-K_lim * (VMAX - x1) + sqrt((K_lim * (VMAX - x1)) ^ 2 + eps_v ^ 2)))
    + (0.5 * (-d - K_lim * (x1 - VMIN) + sqrt((-d - K_lim * (x1 - VMIN)) ^ 2 + eps_v ^ 2))
      - 0.5 * (-K_lim * (x1 - VMIN) + sqrt((K_lim * (x1 - VMIN)) ^ 2 + eps_v ^ 2)));
  der(x2) = (x1 - x2) / T3;
  pm.signal = x2 + T2 / T3 * (x1 - x2) + Dt * dw.signal;
  annotation(Documentation(info="<html>
<p>Source: IEEE PES Power System Dynamic Performance Committee, <i>Dynamic Models for
Turbine-Governors in Power System Studies</i>, technical report PES-TR1 (2013), section 2.1
(TGOV1), and the PSS/E Model Library (TGOV1). Block diagram: (P_ref - dw_PSSE / R) through
1/(1 + s T1) with <b>non-windup</b> limits VMIN..VMAX, then (1 + s T2) / (1 + s T3), minus
Dt * dw_PSSE. PSS/E's speed deviation is w - 1, so here (input dw = w_ref - w) the droop
and damping terms change sign.</p>
<p>Non-windup limits have no state events in the embedded build: the valve's speed is
capped by K_lim times its distance to the limit (a valve pushed outwards settles within
(its free speed) / K_lim of the limit, 6e-4 pu for 0.06 pu/s and the default 100/s), and
the corners are rounded over eps_v; the formula is in the equations.</p>
<p>Initialisation: steady state at the dispatch p_ref (x1 = x2 = p_ref, clamped to the
valve limits). Units: pu on the machine base, s.</p></html>"));
end TGOV1;
