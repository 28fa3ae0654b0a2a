within iGrGen.Governors;
block GGOV1 "General gas-turbine governor GGOV1 (WECC; IEEE PES-TR1 2013, sec. 3.3): governor PID, load and acceleration limiters under a low-value gate"
  parameter Types.PerUnit R(min=0, max=1) = 0.04 "permanent droop (pu)";
  parameter Integer Rselect(min=-1, max=1) = 1 "droop feedback: 1 electrical power, -1 valve stroke, 0 isochronous (PSS/E's integer flag; its -2, governor output, is not offered)";
  parameter Types.Time Tpelec(min=0.001, max=10) = 1.0 "electrical power transducer time constant";
  parameter Types.PerUnit maxerr(min=0, max=1) = 0.05 "largest speed error signal (pu)";
  parameter Types.PerUnit minerr(min=-1, max=0) = -0.05 "smallest speed error signal (pu)";
  parameter Types.PerUnit Kpgov(min=0, max=100) = 10 "governor proportional gain";
  parameter Types.PerUnitRate Kigov(min=0, max=100) = 2 "governor integral gain (1/s)";
  parameter Types.Time Kdgov(min=0, max=100) = 0 "governor derivative gain (s)";
  parameter Types.Time Tdgov(min=0.001, max=10) = 1 "governor derivative filter time constant";
  parameter Types.PerUnit Vmax(min=0, max=2) = 1 "largest valve position (pu)";
  parameter Types.PerUnit Vmin(min=0, max=1) = 0.15 "smallest valve position (pu)";
  parameter Types.Time Tact(min=0.001, max=10) = 0.5 "actuator time constant";
  parameter Types.PerUnit Kturb(min=0.1, max=5) = 1.5 "turbine gain";
  parameter Types.PerUnit Wfnl(min=0, max=1) = 0.2 "no-load fuel flow (pu)";
  parameter Types.Time Tb(min=0.001, max=100) = 0.5 "turbine lag time constant";
  parameter Types.Time Tc(min=0, max=100) = 0 "turbine lead time constant";
  parameter Integer Flag(min=0, max=1) = 1 "fuel flow: 1 proportional to speed, 0 independent of it (PSS/E's integer flag)";
  parameter Types.Time Tfload(min=0.001, max=100) = 3 "load limiter time constant (lag of the temperature path)";
  parameter Types.PerUnit Kpload(min=0, max=100) = 2 "load limiter proportional gain";
  parameter Types.PerUnitRate Kiload(min=0, max=100) = 0.67 "load limiter integral gain (1/s)";
  parameter Types.PerUnit Ldref(min=0, max=2) = 1 "load limiter reference, as mechanical power (pu)";
  parameter Types.PerUnit Dm(min=0, max=1) = 0 "mechanical damping coefficient (pu); PSS/E's negative Dm, a fuel limit falling with speed, is not modelled";
  parameter Types.PerUnitRate Ropen(min=1e-4, max=100) = 0.1 "largest valve opening rate (pu/s)";
  parameter Types.PerUnitRate Rclose(min=-100, max=-1e-4) = -0.1 "largest valve closing rate, negative (pu/s)";
  parameter Types.PerUnitRate Kimw(min=0, max=1) = 0 "power controller (reset) gain (1/s); 0: no power controller";
  parameter Types.PerUnit Pmwset(min=0, max=2) = p_ref "power controller set-point (pu on the machine base, PSS/E gives MW)";
  parameter Types.PerUnitRate aset(min=-1, max=10) = 0.1 "acceleration limiter set-point (pu/s)";
  parameter Types.PerUnit Ka(min=0, max=100) = 10 "acceleration limiter gain";
  parameter Types.Time Ta(min=0.001, max=10) = 0.1 "acceleration limiter time constant";
  parameter Types.PerUnit db(min=0, max=0.1) = 0 "speed governor deadband (pu)";
  parameter Types.Time Tsa(min=0, max=100) = 4 "temperature detection lead time constant";
  parameter Types.Time Tsb(min=0.001, max=100) = 5 "temperature detection lag time constant";
  parameter Types.Time DELT(min=1e-4, max=0.1) = 0.005 "PSS/E's time step: here the lag with which the acceleration limiter reads the gate's output";
  parameter Types.PerUnit p_ref(min=0, max=2) = 0.6 "mechanical power at the dispatch (pu)";
  parameter Types.PerUnit eps_v(min=1e-9, max=0.01) = 1e-4 "sharpness: rounding of the limits and of the low-value gate (pu, pu/s)";
  parameter Types.PerUnitRate K_lim(min=1, max=1e4) = 100 "sharpness of the non-windup limit of the limiters' integrators: held within (their speed) / K_lim of the gate's output";
  parameter Types.PerUnit eps_db(min=1e-9, max=1e-3) = 1e-6 "sharpness: rounding of the deadband's corners (pu of speed)";
  parameter Types.PerUnitRate K_track(min=0.01, max=1e3) = 10 "tracking gain of the governor's integrator while another signal holds the gate (1/s)";
  final parameter Types.PerUnit v0 = p_ref / Kturb + Wfnl "valve position (fuel flow) at the dispatch (pu)";
  final parameter Types.PerUnit ldw = Ldref / Kturb + Wfnl "fuel flow at the load limiter's reference (pu)";
  final parameter Types.PerUnit Pref = R * (if Rselect == 1 then p_ref elseif Rselect == -1 then v0 else 0) "speed-load reference that holds the dispatch (pu)";
  Interfaces.RealInput dw "speed deviation w_ref - w (pu): PSS/E's -SPEED";
  Interfaces.RealInput pelec "electrical power at the terminals (pu): the bench's machine, or pm on a staged test's stiff grid";
  Interfaces.RealOutput pm "mechanical power (pu)";
  Types.PerUnit spd "speed deviation w - 1 as PSS/E reads it, after the deadband (pu)";
  Types.PerUnit pe "electrical power, as the droop on electrical power (Rselect = 1) and the power controller read it (pu)";
  Types.PerUnit pef "measured electrical power (pu)";
  Types.PerUnit xmw "power controller's correction of the reference (pu)";
  Types.PerUnit err "speed error before its limits (pu)";
  Types.PerUnit errl "limited speed error (pu)";
  Types.PerUnit xg "governor PI integrator (pu)";
  Types.PerUnit xd "governor derivative filter state (pu)";
  Types.PerUnit fsrn "governor output (pu)";
  Types.PerUnit xf "temperature path: lagged fuel flow (pu)";
  Types.PerUnit xs "temperature detector lead-lag state (pu)";
  Types.PerUnit texm "measured temperature, as fuel flow (pu)";
  Types.PerUnit xl "load limiter PI integrator (pu)";
  Types.PerUnit fsrt "load limiter output (pu)";
  Types.PerUnit xa "acceleration filter state (pu)";
  Types.PerUnitRate acc "filtered acceleration (pu/s)";
  Types.PerUnit z "the gate's output as the acceleration limiter reads it, DELT late (pu)";
  Types.PerUnit fsra "acceleration limiter output (pu)";
  Types.PerUnit low "smallest of the three (pu)";
  Types.PerUnit fsr "low-value gate output (pu)";
  Types.PerUnit fsrl "gate output within Vmin..Vmax (pu)";
  Types.PerUnit v "valve stroke, the actuator state (pu)";
  Types.PerUnit wf "fuel flow (pu)";
  Types.PerUnit xt "turbine lead-lag state (pu)";
initial equation
  pef = p_ref;
  xmw = 0;
  xg = v0;
  xd = 0;
  xf = v0;
  xs = v0;
  xl = v0;
  xa = 0;
  z = v0;
  v = v0;
  xt = p_ref;
equation
  // speed deviation as PSS/E reads it (w - 1), through the no-jump deadband (db = 0: none)
  spd = -dw.signal + 0.5 * (sqrt((-dw.signal - db) ^ 2 + eps_db ^ 2) - sqrt((-dw.signal + db) ^ 2 + eps_db ^ 2));
  pe = pelec.signal;
  der(pef) = (pe - pef) / Tpelec;
  der(xmw) = Kimw * (Pmwset - pef);
  err = Pref + xmw - R * (if Rselect == 1 then pef elseif Rselect == -1 then v else 0) - spd;
  errl = err - 0.5 * (err - maxerr + sqrt((err - maxerr) ^ 2 + eps_v ^ 2))
             + 0.5 * (minerr - err + sqrt((minerr - err) ^ 2 + eps_v ^ 2));
  der(xd) = (errl - xd) / Tdgov;
  fsrn = Kpgov * errl + xg + Kdgov * (errl - xd) / Tdgov;
  // back-calculation: while the gate or a valve limit holds a lower value, the integrator follows it
  der(xg) = Kigov * errl + K_track * (fsrl - fsrn);
  // load limiter: temperature as fuel flow through Tfload and the detector's lead-lag
  der(xf) = (wf - xf) / Tfload;
  der(xs) = (xf - xs) / Tsb;
  texm = xs + Tsa / Tsb * (xf - xs);
  fsrt = Kpload * (ldw - texm) + xl;
  // its integrator may not rise above the gate's output, and may always fall:
  // speed min(a, max(c, 0)) with a = Kiload x margin, c = K_lim x (fsrl - xl), rounded
  der(xl) = Kiload * (ldw - texm) - 0.5 * (Kiload * (ldw - texm)
      - 0.5 * (K_lim * (fsrl - xl) + sqrt((K_lim * (fsrl - xl)) ^ 2 + eps_v ^ 2))
      + sqrt((Kiload * (ldw - texm) - 0.5 * (K_lim * (fsrl - xl) + sqrt((K_lim * (fsrl - xl)) ^ 2 + eps_v ^ 2))) ^ 2
        + eps_v ^ 2));
  // acceleration limiter: PSS/E's fsr(t - DELT) + Ka DELT (aset - acc), continuous
  der(xa) = (spd - xa) / Ta;
  acc = (spd - xa) / Ta;
  der(z) = (fsrl - z) / DELT;
  fsra = z + Ka * DELT * (aset - acc);
  // low-value gate: -eps log(sum exp(-x / eps)), written from the smallest input
  low = min(fsrn, min(fsrt, fsra));
  fsr = low - eps_v * log(exp((low - fsrn) / eps_v) + exp((low - fsrt) / eps_v) + exp((low - fsra) / eps_v));
  fsrl = fsr - 0.5 * (fsr - Vmax + sqrt((fsr - Vmax) ^ 2 + eps_v ^ 2))
             + 0.5 * (Vmin - fsr + sqrt((Vmin - fsr) ^ 2 + eps_v ^ 2));
  // actuator with opening and closing rate limits, corrected to vanish at rest
  der(v) = (fsrl - v) / Tact
    - 0.5 * ((fsrl - v) / Tact - Ropen + sqrt(((fsrl - v) / Tact - Ropen) ^ 2 + eps_v ^ 2))
    + 0.5 * (-Ropen + sqrt(Ropen ^ 2 + eps_v ^ 2))
    + 0.5 * (Rclose - (fsrl - v) / Tact + sqrt((Rclose - (fsrl - v) / Tact) ^ 2 + eps_v ^ 2))
    - 0.5 * (Rclose + sqrt(Rclose ^ 2 + eps_v ^ 2));
  wf = v * (if Flag == 1 then 1 + spd else 1);
  der(xt) = (Kturb * (wf - Wfnl) - xt) / Tb;
  pm.signal = xt + Tc / Tb * (Kturb * (wf - Wfnl) - xt) - Dm * spd;
  annotation(Documentation(info="<html>
<p>Source: IEEE PES, <i>Dynamic Models for Turbine-Governors in Power System Studies</i>,
PES-TR1 (2013), section 3.3 (GGOV1, the WECC general governor/turbine model) and the
PSS/E and PowerWorld GGOV1 documentation; parameter names, defaults and ranges follow
them (Pmwset in pu here; the flags Rselect and Flag are Integers, as in PSS/E and OpenIPSL). The governor's PID acts on the speed error
Pref + power controller - R x feedback - speed deviation, limited to minerr..maxerr; a
<b>low-value gate</b> takes the smallest of the governor's output, the load limiter's (a
PI on the temperature, read as fuel flow through Tfload and the detector's lead-lag
Tsa/Tsb, against Ldref) and the acceleration limiter's; the result, within Vmin..Vmax,
drives the actuator (Tact, rate limits Ropen/Rclose), fuel flow (times speed if Flag =
1) less the no-load flow, times Kturb, through the turbine lead-lag Tc/Tb, less Dm times
the speed deviation.</p>
<p>Conventions (<b>non-windup</b>): the load limiter's integrator may not rise above the
gate's output and may always fall (its speed is min(Kiload x margin, max(K_lim x
distance to the gate's output, 0))), so that an idle limiter waits Kpload x its margin
above the gate and one holding the gate is a plain PI; the governor's integrator follows the gate's output by
back-calculation (K_track) while another signal holds the gate or the valve is at a
limit. The acceleration limiter is PSS/E's fsr(t - DELT) + Ka DELT (aset - acceleration)
with the delay read as a lag DELT: an integrating control of the acceleration.</p>
<p>The speed deadband db is of the no-step (linear) form, spd - clamp(spd, -db, db),
rounded over its own eps_db (1e-6 pu of speed; until 2026-11-29 over eps_v, which rounds a
36 mHz band's corners over a sixth of its width); exactly none where db = 0.</p>
<p>Smooth forms, as the embedded build has no state events (sharpness eps_v): limits
rounded as min/max(z) = (z -+ sqrt(z^2 + eps^2)) / 2, the gate as
-eps log(sum exp(-x / eps)) (exact to exp(-margin / eps) when one input is clearly the
smallest). Not modelled: the diesel transport lag Teng (0 for gas turbines), the ramp
limits Rup/Rdown of the load limit reference (which a test holds constant), Rselect
= -2 (governor output as feedback, an algebraic loop through the PID), and a negative
Dm (in PSS/E the maximum fuel flow then falls with speed, with no damping on the power:
Dm is held at 0 or above).</p>
<p>The electrical power is an input (pelec): on the stiff grid of a staged test the bench feeds it the mechanical power; on a recorded-frequency bench, Machines.SwingPower's P_e (the mechanical power less the rotor's inertial and damping power). Initial
state: steady at the dispatch p_ref (valve and fuel flow v0 = p_ref / Kturb + Wfnl, the
speed-load reference Pref = R x the feedback's value), which must lie within
Vmin..Vmax and below the load limit. Units: pu on the machine base, s.</p></html>",
    revisions="<html><ul><li>2026-11-24: first version.</li><li>2026-11-25: the electrical power is an input, pelec (issue 26).</li><li>2026-11-27: Rselect and Flag are Integer parameters, as PSS/E and OpenIPSL have them and MLS section 3.5 requires of a comparison with == (issue 35).</li><li>2026-11-27: Dm at 0 or above: PSS/E's negative Dm means a speed-dependent fuel limit, which is not modelled, so a record stating one is refused (issue 40).</li><li>2026-11-29: the deadband rounded over its own eps_db (issue 53).</li></ul></html>"));
end GGOV1;
