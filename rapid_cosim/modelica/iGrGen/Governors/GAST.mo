within iGrGen.Governors;
block GAST "Gas turbine-governor GAST (PSS/E; IEEE PES-TR1 2013, ch. 3)"
  parameter Types.PerUnit R(min=0.001, max=1) = 0.05 "permanent droop (pu)";
  parameter Types.Time T1(min=0.001, max=100) = 0.4 "fuel valve time constant";
  parameter Types.Time T2(min=0.001, max=100) = 0.1 "fuel system (combustion) time constant";
  parameter Types.Time T3(min=0.001, max=100) = 3.0 "load limit time constant: the exhaust temperature's measurement";
  parameter Types.PerUnit AT(min=0, max=2) = 1.0 "ambient temperature load limit (pu)";
  parameter Types.PerUnit KT(min=0, max=10) = 2.0 "temperature limiter gain";
  parameter Types.PerUnit VMAX(min=0, max=2) = 1.0 "maximum fuel valve position (pu)";
  parameter Types.PerUnit VMIN(min=-1, max=2) = 0.0 "minimum fuel valve position (pu)";
  parameter Types.PerUnit Dt(min=0, max=10) = 0.0 "turbine damping coefficient (pu)";
  parameter Types.PerUnit p_ref(min=0, max=2) = 0.6 "power reference, the dispatch (pu)";
  parameter Types.PerUnitRate eps_v(min=1e-9, max=1) = 1e-4 "sharpness: rounding of the non-windup gate and of the low-value gate (pu, pu/s)";
  parameter Types.PerUnitRate K_lim(min=1, max=1e4) = 100 "sharpness of the non-windup limit: a state at a limit is held within (its speed) / K_lim of it";
  Interfaces.RealInput dw "speed deviation w_ref - w (pu): PSS/E's -SPEED";
  Interfaces.RealOutput pm "mechanical power (pu)";
  Types.PerUnit u "speed-load demand: the dispatch plus the droop's correction (pu)";
  Types.PerUnit vt "temperature limit demand (pu)";
  Types.PerUnit low "smaller of the two (pu)";
  Types.PerUnit fsr "low-value gate output (pu)";
  Types.PerUnitRate d "free fuel valve speed (pu/s)";
  Types.PerUnit x1 "fuel valve position, the lag state (pu)";
  Types.PerUnit x2 "fuel flow (pu)";
  Types.PerUnit x3 "exhaust temperature as measured, as power (pu)";
initial equation
  x1 = min(max(p_ref, VMIN), VMAX);
  x2 = x1;
  x3 = x1;
equation
  u = p_ref + dw.signal / R;
  vt = AT + KT * (AT - x3);
  // low-value gate: -eps log(exp(-u / eps) + exp(-vt / eps)), written from the smaller input
  low = min(u, vt);
  fsr = low - eps_v * log(exp((low - u) / eps_v) + exp((low - vt) / eps_v));
  d = (fsr - x1) / T1;
  // non-windup lag on the fuel valve, as TGOV1's valve
  der(x1) = d - (0.5 * (d - K_lim * (VMAX - x1) + sqrt((d - K_lim * (VMAX - x1)) ^ 2 + eps_v ^ 2))
      - 0.5 * (-K_lim * (VMAX - x1) + sqrt((K_lim * (VMAX - x1)) ^ 2 + eps_v ^ 2)))
    + (0.5 * (-d - K_lim * (x1 - VMIN) + sqrt((-d - K_lim * (x1 - VMIN)) ^ 2 + eps_v ^ 2))
      - 0.5 * (-K_lim * (x1 - VMIN) + sqrt((K_lim * (x1 - VMIN)) ^ 2 + eps_v ^ 2)));
  der(x2) = (x1 - x2) / T2;
  der(x3) = (x2 - x3) / T3;
  pm.signal = x2 + Dt * dw.signal;
  annotation(Documentation(info="<html>
<p>Source: IEEE PES, <i>Dynamic Models for Turbine-Governors in Power System Studies</i>,
PES-TR1 (2013), chapter 3 (gas turbines: the simple model GAST), and the PSS/E Model
Library (GAST: R, T1, T2, T3, AT, KT, VMAX, VMIN, Dturb). Block diagram: the speed-load
demand P_ref - dw_PSSE / R and the temperature limit AT + KT (AT - x3) meet in a
<b>low-value gate</b>; its output drives the fuel valve, 1/(1 + s T1) with <b>non-windup</b>
limits VMIN..VMAX; the fuel flow 1/(1 + s T2) is the turbine's power, less Dturb dw_PSSE;
the exhaust temperature, read as that power through 1/(1 + s T3), closes the load limit.
PSS/E's speed deviation is w - 1, so here (input dw = w_ref - w) the droop and damping terms
change sign. The same diagram as ANDES's GAST and ORNL GridKit's GASTPTI.</p>
<p>Smooth forms, as the embedded build has no state events (sharpness eps_v): the gate as
-eps log(sum exp(-x / eps)), exact to exp(-margin / eps) when one input is clearly the
smaller, and the non-windup valve as TGOV1's. No deadband: PSS/E's GAST has none (GASTD is
not offered).</p>
<p>Initialisation: steady state at the dispatch p_ref (x1 = x2 = x3 = p_ref, clamped to the
valve limits), which must lie below the temperature limit AT. Units: pu on the machine
base, s.</p></html>",
    revisions="<html><ul><li>2026-11-29: first version (issue 53).</li></ul></html>"));
end GAST;
