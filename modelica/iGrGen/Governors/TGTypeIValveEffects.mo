within iGrGen.Governors;
block TGTypeIValveEffects "TG Type I with rate limits, backlash and a load controller together (for combinations)"
  extends PartialTGTypeI;
  parameter Real rate_open(unit="1/s", min=1e-4, max=1e3) = 100 "largest opening speed of the valve (pu/s); the default never binds";
  parameter Real rate_close(unit="1/s", min=1e-4, max=1e3) = 100 "largest closing speed of the valve, a magnitude (pu/s); the default never binds";
  parameter Real eps_rate(unit="1/s", min=1e-9, max=1) = 1e-4 "sharpness: width of the rounded corners of the smooth limit (pu/s)";
  parameter Real backlash(unit="1", min=0, max=0.5) = 0 "total width of the play (pu of valve position); 0: none";
  parameter Real T_bl(unit="s", min=1e-4, max=10) = 0.05 "sharpness: time constant with which the valve follows once the play is taken up";
  parameter Real eps_bl(unit="1", min=1e-9, max=0.1) = 1e-4 "sharpness: smoothing width of the dead zone edges (pu)";
  parameter Real K_lc(unit="1/s", min=0, max=10) = 0 "integral gain of the outer load loop (1/s); 0: none";
  Real v_free "valve speed the governor asks for (pu/s)";
  Real gap "governor position minus valve position (pu)";
  Real dp_lc(start=0, fixed=true) "load controller's correction of the reference (pu)";
initial equation
  xg1 = pin;
  xv = xg1;
equation
  // The three mechanisms of TGTypeIRateLimit, TGTypeIBacklash and TGTypeILoadControl, in
  // series; each is written exactly as there, so that one switched off leaves the others'
  // behaviour unchanged (backlash = 0 leaves only the T_bl follower lag).
  pin_star = p_ref + dp_lc + dw.signal / R;
  der(dp_lc) = K_lc * (p_ref - pm.signal);
  v_free = (pin - xg1) / Ts;
  der(xg1) = v_free
    - 0.5 * (v_free - rate_open + sqrt((v_free - rate_open) ^ 2 + eps_rate ^ 2))
    + 0.5 * (-rate_open + sqrt(rate_open ^ 2 + eps_rate ^ 2))
    + 0.5 * (-rate_close - v_free + sqrt((-rate_close - v_free) ^ 2 + eps_rate ^ 2))
    - 0.5 * (-rate_close + sqrt(rate_close ^ 2 + eps_rate ^ 2));
  gap = xg1 - xv;
  T_bl * der(xv) = max(gap - backlash / 2, 0) + eps_bl * log(1 + exp(-abs(gap - backlash / 2) / eps_bl))
                 - max(-gap - backlash / 2, 0) - eps_bl * log(1 + exp(-abs(-gap - backlash / 2) / eps_bl));
end TGTypeIValveEffects;
