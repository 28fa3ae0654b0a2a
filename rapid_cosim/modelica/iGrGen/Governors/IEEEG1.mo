within iGrGen.Governors;
block IEEEG1 "Multi-stage steam turbine-governor IEEEG1 (IEEE 1973; IEEE PES-TR1 2013, sec. 2.2)"
  parameter Types.PerUnit K(min=1, max=100) = 20 "governor gain, 1/droop (pu)";
  parameter Types.Time T1(min=0.001, max=100) = 0.001 "governor lag time constant (PSS/E's 0 is 0.001 here)";
  parameter Types.Time T2(min=0, max=100) = 0.0 "governor lead time constant";
  parameter Types.Time T3(min=0.001, max=10) = 0.1 "valve positioner time constant";
  parameter Types.PerUnitRate Uo(min=1e-4, max=10) = 1.0 "maximum valve opening rate (pu/s)";
  parameter Types.PerUnitRate Uc(min=-10, max=-1e-4) = -1.0 "maximum valve closing rate (pu/s, negative)";
  parameter Types.PerUnit PMAX(min=0, max=2) = 1.0 "maximum valve opening (pu)";
  parameter Types.PerUnit PMIN(min=0, max=2) = 0.0 "minimum valve opening (pu)";
  parameter Types.Time T4(min=0.001, max=100) = 0.3 "inlet piping / steam bowl time constant";
  parameter Types.PerUnit K1(min=0, max=1) = 0.2 "fraction of the HP shaft power after the first stage";
  parameter Types.Time T5(min=0.001, max=100) = 7.0 "second stage (reheater) time constant";
  parameter Types.PerUnit K3(min=0, max=1) = 0.3 "fraction of the HP shaft power after the second stage (with K3_rest = 0)";
  parameter Real K3_rest(min=0, max=1) = 0 "1: K3 is the rest of the shaft power, 1 - K1 - K5 - K7, so the stages sum to one (a single-reheat unit; K3 as given is not used); 0: K3 as given";
  parameter Types.Time T6(min=0.001, max=100) = 0.6 "third stage time constant";
  parameter Types.PerUnit K5(min=0, max=1) = 0.5 "fraction of the HP shaft power after the third stage";
  parameter Types.Time T7(min=0.001, max=100) = 0.05 "fourth stage (second reheater) time constant";
  parameter Types.PerUnit K7(min=0, max=1) = 0.0 "fraction of the HP shaft power after the fourth stage";
  parameter Types.PerUnit db(min=0, max=0.01) = 0 "speed deadband, half-width (pu of speed; no-step form): IEEEG1D's dbH = -dbL; 0: none";
  parameter Types.PerUnit p_ref(min=0, max=2) = 0.6 "power at the dispatch (pu)";
  parameter Types.PerUnitRate eps_v(min=1e-9, max=1) = 1e-4 "sharpness: rounding of the rate limits and the gate (pu/s)";
  parameter Types.PerUnitRate K_lim(min=1, max=1e4) = 100 "sharpness of the non-windup limit: a state at a limit is held within (its speed) / K_lim of it";
  parameter Types.PerUnit eps_db(min=1e-9, max=1e-3) = 1e-6 "sharpness: rounding of the deadband's corners (pu of speed)";
  final parameter Types.PerUnit K3s = if K3_rest > 0.5 then 1 - K1 - K5 - K7 else K3 "the second stage's fraction in use (pu)";
  final parameter Types.PerUnit gv0 = p_ref / (K1 + K3s + K5 + K7) "valve opening at the dispatch (pu)";
  Interfaces.RealInput dw "speed deviation w_ref - w (pu): PSS/E's -SPEED";
  Interfaces.RealOutput pm "mechanical power of the HP shaft (pu)";
  Types.PerUnit dwd "speed deviation after the deadband (pu)";
  Types.PerUnit xl "governor lead-lag state (pu)";
  Types.PerUnit ysp "speed signal after K (1 + s T2) / (1 + s T1) (pu)";
  Types.PerUnitRate v "valve speed the positioner asks for (pu/s)";
  Types.PerUnitRate vl "rate-limited valve speed (pu/s)";
  Types.PerUnit gv "valve opening (pu)";
  Types.PerUnit x4 "first stage (pu)";
  Types.PerUnit x5 "second stage (pu)";
  Types.PerUnit x6 "third stage (pu)";
  Types.PerUnit x7 "fourth stage (pu)";
initial equation
  xl = 0;
  gv = gv0;
  x4 = gv0;
  x5 = gv0;
  x6 = gv0;
  x7 = gv0;
equation
  // no-step deadband: dw - clamp(dw, -db, db), rounded over eps_db; exactly dw where db = 0
  dwd = dw.signal + 0.5 * (sqrt((dw.signal - db) ^ 2 + eps_db ^ 2) - sqrt((dw.signal + db) ^ 2 + eps_db ^ 2));
  der(xl) = (dwd - xl) / T1;
  ysp = K * (xl + T2 / T1 * (dwd - xl));
  v = (gv0 + ysp - gv) / T3;
  // rate limits Uc <= vl <= Uo, smooth, corrected to vanish at v = 0
  vl = v - 0.5 * (v - Uo + sqrt((v - Uo) ^ 2 + eps_v ^ 2)) + 0.5 * (-Uo + sqrt(Uo ^ 2 + eps_v ^ 2))
    + 0.5 * (Uc - v + sqrt((Uc - v) ^ 2 + eps_v ^ 2)) - 0.5 * (Uc + sqrt(Uc ^ 2 + eps_v ^ 2));
  // non-windup position limits PMIN..PMAX on the valve integrator (as TGOV1's valve)
  der(gv) = vl - (0.5 * (vl - K_lim * (PMAX - gv) + sqrt((vl - K_lim * (PMAX - gv)) ^ 2 + eps_v ^ 2))
      - 0.5 * (-K_lim * (PMAX - gv) + sqrt((K_lim * (PMAX - gv)) ^ 2 + eps_v ^ 2)))
    + (0.5 * (-vl - K_lim * (gv - PMIN) + sqrt((-vl - K_lim * (gv - PMIN)) ^ 2 + eps_v ^ 2))
      - 0.5 * (-K_lim * (gv - PMIN) + sqrt((K_lim * (gv - PMIN)) ^ 2 + eps_v ^ 2)));
  der(x4) = (gv - x4) / T4;
  der(x5) = (x4 - x5) / T5;
  der(x6) = (x5 - x6) / T6;
  der(x7) = (x6 - x7) / T7;
  pm.signal = K1 * x4 + K3s * x5 + K5 * x6 + K7 * x7;
  annotation(Documentation(info="<html>
<p>Source: IEEE Committee Report, <i>Dynamic models for steam and hydro turbines in power
system studies</i>, IEEE Trans. PAS-92 (1973) 1904-1915, fig. 1 and 6; IEEE PES-TR1 (2013),
section 2.2 (IEEEG1); PSS/E Model Library (IEEEG1). The speed signal K (1 + s T2) / (1 + s T1)
adds to the reference; the valve positioner 1/T3 is rate-limited (Uc..Uo) and integrates
to the valve opening, held in PMIN..PMAX (<b>non-windup</b>); four stages T4..T7 with
fractions K1, K3, K5, K7 make the power of the high-pressure shaft.</p>
<p>Single shaft only: the low-pressure fractions K2, K4, K6, K8 of a cross-compound unit
are not modelled. PSS/E allows T1 = 0 (no lag): here T1 is at least 0.001 s.
K3_rest = 1 makes K3 the rest of the shaft power, 1 - K1 - K5 - K7: a single-reheat unit
whose stages sum to one (PES-TR1 sec. 2.2 gives the fractions of one shaft; ANDES normalises
them to sum to one), so that K alone sets the droop; a unit documented with another split
keeps K3_rest = 0 and K3 as documented.</p>
<p>Limits are smooth (eps_v; the non-windup limit holds a state within its speed / K_lim of the limit, as TGOV1's) as the embedded build has no state events.
Deadband (IEEEG1D: PowerWorld's IEEEG1 with dbH, dbL and Trate; ORNL GridKit's IEEEG1D):
the speed deviation passes a symmetric deadband of half-width db before the governor's
lead-lag, of the no-step (linear) form, dw - clamp(dw, -db, db), rounded over eps_db as
TGOV1's; exactly the plain IEEEG1 where db = 0.
Initialisation: steady state at p_ref: every stage at p_ref / (K1 + K3 + K5 + K7), K3 as in use.
Units: pu on the machine base, s.</p></html>",
    revisions="<html><ul><li>2026-11-23: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li><li>2026-11-26: K3_rest, the stages summing to one.</li><li>2026-11-29: the speed deadband db, IEEEG1D (issue 53).</li></ul></html>"));
end IEEEG1;
