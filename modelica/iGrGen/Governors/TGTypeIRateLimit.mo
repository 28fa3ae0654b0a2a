within iGrGen.Governors;
block TGTypeIRateLimit "TG Type I with separate opening and closing rate limits on the valve"
  extends PartialTGTypeI;
  parameter Real rate_open(unit="1/s", min=1e-4, max=10) = 0.01 "largest opening speed of the valve (pu/s)";
  parameter Real rate_close(unit="1/s", min=1e-4, max=10) = 0.02 "largest closing speed of the valve, a magnitude (pu/s)";
  parameter Real eps_rate(unit="1/s", min=1e-9, max=1) = 1e-4 "sharpness: width of the rounded corners of the smooth limit (pu/s)";
  Real v_free "valve speed the governor asks for (pu/s)";
initial equation
  xg1 = pin;
equation
  pin_star = p_ref + dw.signal / R;                                        // (1)
  v_free = (pin - xg1) / Ts;
  // (3) through a smooth clamp to [-rate_close, rate_open]; the corrections vanish at
  // v_free = 0 exactly, so the steady state is that of (3).
  der(xg1) = v_free
    - 0.5 * (v_free - rate_open + sqrt((v_free - rate_open) ^ 2 + eps_rate ^ 2))
    + 0.5 * (-rate_open + sqrt(rate_open ^ 2 + eps_rate ^ 2))
    + 0.5 * (-rate_close - v_free + sqrt((-rate_close - v_free) ^ 2 + eps_rate ^ 2))
    - 0.5 * (-rate_close + sqrt(rate_close ^ 2 + eps_rate ^ 2));
  xv = xg1;
end TGTypeIRateLimit;
