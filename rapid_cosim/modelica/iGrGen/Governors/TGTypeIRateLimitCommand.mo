within iGrGen.Governors;
block TGTypeIRateLimitCommand "TG Type I with opening and closing rate limits on the governor's command"
  extends PartialTGTypeI;
  parameter Types.PerUnitRate rate_open(min=1e-4, max=10) = 0.01 "largest rising speed of the command (pu/s)";
  parameter Types.PerUnitRate rate_close(min=1e-4, max=10) = 0.02 "largest falling speed of the command, a magnitude (pu/s)";
  parameter Types.PerUnitRate eps_rate(min=1e-9, max=1) = 1e-4 "sharpness: width of the rounded corners of the smooth limit (pu/s)";
  parameter Types.Time T_rl(min=1e-3, max=1) = 0.02 "sharpness: time constant with which the command follows when not limited";
  Effects.RateLimitedLag ramp(final T = T_rl, final rate_open = rate_open, final rate_close = rate_close,
    final eps_rate = eps_rate) "the command's ramp-rate limiter";
initial equation
  der(xg1) = 0;
equation
  pin_star = p_ref + dw.signal / R;                                        // (1)
  ramp.u.signal = pin;
  der(xg1) = (ramp.y.signal - xg1) / Ts;                                   // (3), fed the ramped command
  xv = xg1;
  annotation(Documentation(info="<html>
<p>TG Type I (Bogodorova et al. 2016, eqs. 1-6) whose power command is ramp-rate limited
before the governor lag (3), as a plant's load-rate limiter acts on the reference rather
than on the valve: the catalogue's <code>rate_limit_command</code> variant of
<code>rate_limit</code>, which limits the lag's own speed (TGTypeIRateLimit). The limited
command then passes through Ts, so the valve ramps with rounded ends; a freed T4 can
imitate the rounding, and the diagnosis tries this variant before it blames the
documentation.</p></html>",
    revisions="<html><ul><li>2026-11-25: first version.</li></ul></html>"));
end TGTypeIRateLimitCommand;
