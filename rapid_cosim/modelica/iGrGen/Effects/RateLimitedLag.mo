within iGrGen.Effects;
block RateLimitedLag "First-order lag whose speed is limited separately each way (a valve actuator)"
  extends Interfaces.SISO;
  parameter Types.Time T(min=0.001, max=100) = 0.5 "time constant of the free lag";
  parameter Types.PerUnitRate rate_open(min=1e-4, max=1e3) = 0.01 "largest rising speed (pu/s)";
  parameter Types.PerUnitRate rate_close(min=1e-4, max=1e3) = 0.02 "largest falling speed, a magnitude (pu/s)";
  parameter Types.PerUnitRate eps_rate(min=1e-9, max=1) = 1e-4 "sharpness: width of the rounded corners of the smooth limit (pu/s)";
  Types.PerUnitRate v_free "speed the free lag would have (pu/s)";
  Types.PerUnit x "output, the lag state (pu)";
initial equation
  x = u.signal;
equation
  v_free = (u.signal - x) / T;
  // The free speed through a smooth clamp to [-rate_close, rate_open]; the corrections
  // vanish at v_free = 0 exactly, so the steady state is that of the free lag.
  der(x) = v_free
    - 0.5 * (v_free - rate_open + sqrt((v_free - rate_open) ^ 2 + eps_rate ^ 2))
    + 0.5 * (-rate_open + sqrt(rate_open ^ 2 + eps_rate ^ 2))
    + 0.5 * (-rate_close - v_free + sqrt((-rate_close - v_free) ^ 2 + eps_rate ^ 2))
    - 0.5 * (-rate_close + sqrt(rate_close ^ 2 + eps_rate ^ 2));
  y.signal = x;
  annotation(Documentation(info="<html>
<p>The governor's valve lag, equation (3) of Bogodorova et al. (2016), with the actuator's
opening and closing speed limits. A hard clamp of the speed would be a state event; the
smooth form min/max(z) = (z +- sqrt(z^2 + eps^2)) / 2 rounds the corners over eps_rate
and is exact away from them. Starts at rest (x = u).</p></html>",
    revisions="<html><ul><li>2026-11: one block for TGTypeIRateLimit and TGTypeIValveEffects, which each held a copy of these equations.</li></ul></html>"));
end RateLimitedLag;
