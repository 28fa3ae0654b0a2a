within iGrGen.Governors;
block HYGOV "Hydro turbine-governor HYGOV with the water column (PSS/E; IEEE PES-TR1 2013, sec. 4.1)"
  parameter Types.PerUnit R(min=0.001, max=1) = 0.05 "permanent droop (pu)";
  parameter Types.PerUnit r(min=0.001, max=5) = 0.3 "temporary droop (pu)";
  parameter Types.Time Tr(min=0.001, max=100) = 5.0 "governor (reset) time constant";
  parameter Types.Time Tf(min=0.001, max=10) = 0.05 "filter time constant";
  parameter Types.Time Tg(min=0.001, max=10) = 0.5 "gate servo time constant";
  parameter Types.PerUnitRate VELM(min=1e-4, max=10) = 0.2 "gate velocity limit (pu/s)";
  parameter Types.PerUnit GMAX(min=0, max=2) = 1.0 "maximum gate opening (pu)";
  parameter Types.PerUnit GMIN(min=0, max=2) = 0.0 "minimum gate opening (pu)";
  parameter Types.Time TW(min=0.01, max=10) = 1.0 "water inertia time constant";
  parameter Types.PerUnit At(min=0.5, max=2) = 1.2 "turbine gain";
  parameter Types.PerUnit Dturb(min=0, max=5) = 0.5 "turbine damping (pu)";
  parameter Types.PerUnit qNL(min=0, max=0.5) = 0.08 "no-load water flow (pu)";
  parameter Types.PerUnit db(min=0, max=0.01) = 0 "speed deadband, half-width (pu of speed; no-step form): HYGOVD's dbH = -dbL; 0: none";
  parameter Types.PerUnit p_ref(min=0, max=2) = 0.6 "power at the dispatch (pu)";
  parameter Types.PerUnitRate eps_v(min=1e-9, max=1) = 1e-4 "sharpness: rounding of the velocity limit and the gate (pu/s)";
  parameter Types.PerUnitRate K_lim(min=1, max=1e4) = 100 "sharpness of the non-windup limit: a state at a limit is held within (its speed) / K_lim of it";
  parameter Types.PerUnit eps_db(min=1e-9, max=1e-3) = 1e-6 "sharpness: rounding of the deadband's corners (pu of speed)";
  final parameter Types.PerUnit q0 = p_ref / At + qNL "water flow at the dispatch, head 1 (pu)";
  final parameter Types.PerUnit nref = R * q0 "speed reference that holds the dispatch (pu)";
  Interfaces.RealInput dw "speed deviation w_ref - w (pu): PSS/E's -SPEED";
  Interfaces.RealOutput pm "mechanical power (pu)";
  Types.PerUnit dwd "speed deviation after the deadband (pu)";
  Types.PerUnit e "filtered speed error (pu)";
  Types.PerUnit xi "integral part of the desired gate (pu)";
  Types.PerUnit c "desired gate opening (pu)";
  Types.PerUnit g "gate opening (pu)";
  Types.PerUnit q "water flow (pu)";
  Types.PerUnit h "head at the turbine (pu)";
  Types.PerUnitRate v "free speed of the integral part (pu/s)";
  Types.PerUnitRate vl "velocity-limited speed (pu/s)";
initial equation
  e = 0;
  xi = q0;
  g = q0;
  q = q0;
equation
  // no-step deadband: dw - clamp(dw, -db, db), rounded over eps_db; exactly dw where db = 0
  dwd = dw.signal + 0.5 * (sqrt((dw.signal - db) ^ 2 + eps_db ^ 2) - sqrt((dw.signal + db) ^ 2 + eps_db ^ 2));
  der(e) = (nref + dwd - R * c - e) / Tf;
  v = e / (r * Tr);
  // velocity limit |vl| <= VELM, smooth: v - sp(v - VELM) + sp(-VELM - v), corrected to vanish at v = 0
  vl = v - 0.5 * (v - VELM + sqrt((v - VELM) ^ 2 + eps_v ^ 2)) + 0.5 * (-VELM + sqrt(VELM ^ 2 + eps_v ^ 2))
    + 0.5 * (-VELM - v + sqrt((VELM + v) ^ 2 + eps_v ^ 2)) - 0.5 * (-VELM + sqrt(VELM ^ 2 + eps_v ^ 2));
  // non-windup position limits GMIN..GMAX on the integral part, as TGOV1's valve
  der(xi) = vl - (0.5 * (vl - K_lim * (GMAX - xi) + sqrt((vl - K_lim * (GMAX - xi)) ^ 2 + eps_v ^ 2))
      - 0.5 * (-K_lim * (GMAX - xi) + sqrt((K_lim * (GMAX - xi)) ^ 2 + eps_v ^ 2)))
    + (0.5 * (-vl - K_lim * (xi - GMIN) + sqrt((-vl - K_lim * (xi - GMIN)) ^ 2 + eps_v ^ 2))
      - 0.5 * (-K_lim * (xi - GMIN) + sqrt((K_lim * (xi - GMIN)) ^ 2 + eps_v ^ 2)));
  c = xi + e / r;
  der(g) = (c - g) / Tg;
  h = (q / g) ^ 2;
  der(q) = (1 - h) / TW;
  pm.signal = At * h * (q - qNL) + Dturb * dwd * g;
  annotation(Documentation(info="<html>
<p>Source: IEEE PES-TR1 (2013), section 4.1 (HYGOV), and the PSS/E Model Library (HYGOV).
Speed error (n_ref - dw_PSSE - R c) through the filter 1/(1 + s Tf); the governor's
PI with transient droop, (1 + s Tr) / (r Tr s), gives the desired gate c, its integral
part velocity-limited to VELM and held in GMIN..GMAX (<b>non-windup</b>); the gate follows
through 1/(1 + s Tg). Water column: TW dq/dt = 1 - h with h = (q / g)^2 (the gate as an
orifice), power At h (q - qNL) - Dturb dw_PSSE g. Opening the gate first drops the head:
the water-hammer zero (power dips before it rises).</p>
<p>Limits are smooth (eps_v; the non-windup limit holds a state within its speed / K_lim of the limit, as TGOV1's) as the embedded build has no state events; the
velocity limit acts on the integral path, as in PSS/E's implementation.</p>
<p>Deadband (HYGOVD: PowerWorld's HYGOV with dbH, dbL and Trate; ORNL GridKit's HYGOVD):
the speed deviation passes a symmetric deadband of half-width db before the speed error
and the turbine damping, of the no-step (linear) form, dw - clamp(dw, -db, db), rounded
over eps_db as TGOV1's; exactly the plain HYGOV where db = 0.</p>
<p>Initialisation: steady state at p_ref: q = g = c = p_ref / At + qNL, h = 1, and the
speed reference n_ref = R q. Units: pu on the machine base, s.</p></html>",
    revisions="<html><ul><li>2026-11-23: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li><li>2026-11-29: the speed deadband db, HYGOVD (issue 53).</li></ul></html>"));
end HYGOV;
