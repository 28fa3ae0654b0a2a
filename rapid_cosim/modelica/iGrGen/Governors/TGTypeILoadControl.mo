within iGrGen.Governors;
block TGTypeILoadControl "TG Type I under a slow load controller that pulls power back to p_ref"
  extends PartialTGTypeI;
  parameter Types.PerUnitRate K_lc(min=0, max=10) = 0.005 "integral gain of the outer load loop (1/s); 1/K_lc is the withdrawal time constant";
  Effects.LoadController lc(final K_lc = K_lc, final p_ref = p_ref) "outer load loop";
initial equation
  der(xg1) = 0;
equation
  lc.u.signal = pm.signal;
  pin_star = p_ref + lc.y.signal + dw.signal / R;                          // (1) with the outer loop
  der(xg1) = (pin - xg1) / Ts;                                             // (3)
  xv = xg1;
  annotation(Documentation(info="<html>
<p>TG Type I (Bogodorova et al. 2016, eqs. 1-6) whose reference is corrected by a slow
integral load loop: the catalogue's <code>load_controller</code> effect.</p></html>",
    revisions="<html><ul><li>2026-11: the loop is Effects.LoadController, shared with TGTypeIValveEffects.</li></ul></html>"));
end TGTypeILoadControl;
