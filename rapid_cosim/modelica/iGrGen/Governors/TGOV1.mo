within iGrGen.Governors;
block TGOV1 "Steam turbine-governor TGOV1 (PSS/E; IEEE PES-TR1 2013, sec. 2.1)"
  parameter Types.PerUnit R(min=0.001, max=1) = 0.05 "permanent droop (pu)";
  parameter Types.Time T1(min=0.001, max=100) = 0.5 "steam bowl / governor time constant";
  parameter Types.PerUnit VMAX(min=0, max=2) = 1.0 "maximum valve position (pu)";
  parameter Types.PerUnit VMIN(min=0, max=2) = 0.0 "minimum valve position (pu)";
  parameter Types.Time T2(min=0, max=100) = 2.5 "numerator (lead) time constant of the reheater";
  parameter Types.Time T3(min=0.001, max=100) = 7.5 "reheater time constant";
  parameter Types.PerUnit Dt(min=0, max=10) = 0.0 "turbine damping coefficient (pu)";
  parameter Types.PerUnit db(min=0, max=0.01) = 0 "speed deadband, half-width (pu of speed; no-step form): TGOV1D's dbH = -dbL; 0: none";
  parameter Types.PerUnit p_ref(min=0, max=2) = 0.6 "power reference, the dispatch (pu)";
  parameter Types.PerUnitRate eps_v(min=1e-9, max=1) = 1e-4 "sharpness: rounding of the non-windup gate in valve speed (pu/s)";
  parameter Types.PerUnitRate K_lim(min=1, max=1e4) = 100 "sharpness of the non-windup limit: a state at a limit is held within (its speed) / K_lim of it";
  parameter Types.PerUnit eps_db(min=1e-9, max=1e-3) = 1e-6 "sharpness: rounding of the deadband's corners (pu of speed)";
  Interfaces.RealInput dw "speed deviation w_ref - w (pu): PSS/E's -SPEED";
  Interfaces.RealOutput pm "mechanical power (pu)";
  Types.PerUnit dwd "speed deviation after the deadband (pu)";
  Types.PerUnit u "valve command before the lag (pu)";
  Types.PerUnitRate d "free valve speed (pu/s)";
  Types.PerUnit x1 "valve position, the lag state (pu)";
  Types.PerUnit x2 "reheater state (pu)";
initial equation
  x1 = min(max(p_ref, VMIN), VMAX);
  x2 = x1;
equation
  // no-step deadband: dw - clamp(dw, -db, db), rounded over eps_db; exactly dw where db = 0
  dwd = dw.signal + 0.5 * (sqrt((dw.signal - db) ^ 2 + eps_db ^ 2) - sqrt((dw.signal + db) ^ 2 + eps_db ^ 2));
  u = p_ref + dwd / R;
  d = (u - x1) / T1;
  // Non-windup lag: the valve stops at a limit and leaves it as soon as the command turns
  // back. The speed is min(d, K_lim (VMAX - x1)) and max(., -K_lim (x1 - VMIN)), rounded
  // with sp(z) = (z + sqrt(z^2 + eps_v^2)) / 2 and corrected to vanish at d = 0.
  der(x1) = d - (0.5 * (d - K_lim * (VMAX - x1) + sqrt((d - K_lim * (VMAX - x1)) ^ 2 + eps_v ^ 2))
      - 0.5 * (-K_lim * (VMAX - x1) + sqrt((K_lim * (VMAX - x1)) ^ 2 + eps_v ^ 2)))
    + (0.5 * (-d - K_lim * (x1 - VMIN) + sqrt((-d - K_lim * (x1 - VMIN)) ^ 2 + eps_v ^ 2))
      - 0.5 * (-K_lim * (x1 - VMIN) + sqrt((K_lim * (x1 - VMIN)) ^ 2 + eps_v ^ 2)));
  der(x2) = (x1 - x2) / T3;
  pm.signal = x2 + T2 / T3 * (x1 - x2) + Dt * dwd;
  annotation(Documentation(info="<html>
<p>Source: IEEE PES Power System Dynamic Performance Committee, <i>Dynamic Models for
Turbine-Governors in Power System Studies</i>, technical report PES-TR1 (2013), section 2.1
(TGOV1), and the PSS/E Model Library (TGOV1). Block diagram: (P_ref - dw_PSSE / R) through
1/(1 + s T1) with <b>non-windup</b> limits VMIN..VMAX, then (1 + s T2) / (1 + s T3), minus
Dt * dw_PSSE. PSS/E's speed deviation is w - 1, so here (input dw = w_ref - w) the droop
and damping terms change sign.</p>
<p>Deadband (TGOV1D: PowerWorld's TGOV1 with dbH, dbL and Trate; ORNL GridKit's TGOV1D;
ANDES's TGOV1DB): the speed deviation passes a symmetric deadband of half-width db before
the droop and the damping, of the no-step (linear) form: outside the band the deviation
acts reduced by the band, dw - clamp(dw, -db, db) (IEEE PES-TR1 (2013), the intentional
deadband without a step). Rounded over eps_db (1e-6 pu of speed: at the band's edge the
deviation is eps_db / 2 off), and exactly the plain TGOV1 where db = 0.</p>
<p>Non-windup limits have no state events in the embedded build: the valve's speed is
capped by K_lim times its distance to the limit (a valve pushed outwards settles within
(its free speed) / K_lim of the limit, 6e-4 pu for 0.06 pu/s and the default 100/s), and
the corners are rounded over eps_v; the formula is in the equations.</p>
<p>Initialisation: steady state at the dispatch p_ref (x1 = x2 = p_ref, clamped to the
valve limits). Units: pu on the machine base, s.</p></html>",
    revisions="<html><ul><li>2026-11-23: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li><li>2026-11-29: the speed deadband db, TGOV1D (issue 53).</li></ul></html>"));
end TGOV1;
