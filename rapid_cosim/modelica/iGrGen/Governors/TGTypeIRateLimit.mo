within iGrGen.Governors;
block TGTypeIRateLimit "TG Type I with separate opening and closing rate limits on the valve"
  extends PartialTGTypeI;
  parameter Types.PerUnitRate rate_open(min=1e-4, max=10) = 0.01 "largest opening speed of the valve (pu/s)";
  parameter Types.PerUnitRate rate_close(min=1e-4, max=10) = 0.02 "largest closing speed of the valve, a magnitude (pu/s)";
  parameter Types.PerUnitRate eps_rate(min=1e-9, max=1) = 1e-4 "sharpness: width of the rounded corners of the smooth limit (pu/s)";
  Effects.RateLimitedLag valve(final T = Ts, final rate_open = rate_open, final rate_close = rate_close,
    final eps_rate = eps_rate) "(3) with the actuator's speed limits";
equation
  pin_star = p_ref + dw.signal / R;                                        // (1)
  valve.u.signal = pin;
  xg1 = valve.y.signal;                                                    // (3), rate-limited
  xv = xg1;
  annotation(Documentation(info="<html>
<p>TG Type I (Bogodorova et al. 2016, eqs. 1-6) with the valve lag (3) limited in speed,
opening and closing separately: the catalogue's <code>rate_limit</code> effect.</p></html>",
    revisions="<html><ul><li>2026-11: the rate-limited lag is Effects.RateLimitedLag, shared with TGTypeIValveEffects.</li></ul></html>"));
end TGTypeIRateLimit;
