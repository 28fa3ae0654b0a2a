within iGrGen.Governors;
block TGTypeIValveEffects "TG Type I with rate limits, backlash and a load controller together (for combinations)"
  extends PartialTGTypeI;
  parameter Types.PerUnitRate rate_open(min=1e-4, max=1e3) = 100 "largest opening speed of the valve (pu/s); the default never binds";
  parameter Types.PerUnitRate rate_close(min=1e-4, max=1e3) = 100 "largest closing speed of the valve, a magnitude (pu/s); the default never binds";
  parameter Types.PerUnitRate eps_rate(min=1e-9, max=1) = 1e-4 "sharpness: width of the rounded corners of the smooth limit (pu/s)";
  parameter Types.PerUnit backlash(min=0, max=0.5) = 0 "total width of the play (pu of valve position); 0: none";
  parameter Types.Time T_bl(min=1e-4, max=10) = 0.05 "sharpness: time constant with which the valve follows once the play is taken up";
  parameter Types.PerUnit eps_bl(min=1e-9, max=0.1) = 1e-4 "sharpness: smoothing width of the dead zone edges (pu)";
  parameter Types.PerUnitRate K_lc(min=0, max=10) = 0 "integral gain of the outer load loop (1/s); 0: none";
  Effects.LoadController lc(final K_lc = K_lc, final p_ref = p_ref) "outer load loop";
  Effects.RateLimitedLag valve(final T = Ts, final rate_open = rate_open, final rate_close = rate_close,
    final eps_rate = eps_rate) "(3) with the actuator's speed limits";
  Effects.Backlash play(final backlash = backlash, final T_bl = T_bl, final eps_bl = eps_bl) "linkage play";
equation
  // The blocks of TGTypeILoadControl, TGTypeIRateLimit and TGTypeIBacklash in series, so
  // that one switched off leaves the others' behaviour unchanged (backlash = 0 leaves
  // only the T_bl follower lag).
  lc.u.signal = pm.signal;
  pin_star = p_ref + lc.y.signal + dw.signal / R;
  valve.u.signal = pin;
  connect(valve.y, play.u);
  xg1 = valve.y.signal;
  xv = play.y.signal;
  annotation(Documentation(info="<html>
<p>TG Type I (Bogodorova et al. 2016, eqs. 1-6) with every valve-side effect of the
catalogue at once; the diagnosis composes pairs of effects on it, with the unused ones
at their off values.</p></html>",
    revisions="<html><ul><li>2026-11: built from Effects.LoadController, RateLimitedLag and Backlash joined by connect, instead of copies of their equations.</li></ul></html>"));
end TGTypeIValveEffects;
