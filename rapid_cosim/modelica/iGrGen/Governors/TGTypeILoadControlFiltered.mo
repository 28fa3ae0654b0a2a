within iGrGen.Governors;
block TGTypeILoadControlFiltered "TG Type I under a slow load controller acting on filtered power"
  extends PartialTGTypeI;
  parameter Types.PerUnitRate K_lc(min=0, max=10) = 0.005 "integral gain of the outer load loop (1/s)";
  parameter Types.Time T_f(min=0.01, max=1000) = 10 "time constant of the filter on the loop's power measurement";
  Effects.LoadControllerFiltered lc(final K_lc = K_lc, final T_f = T_f, final p_ref = p_ref) "outer load loop";
initial equation
  der(xg1) = 0;
equation
  lc.u.signal = pm.signal;
  pin_star = p_ref + lc.y.signal + dw.signal / R;                          // (1) with the outer loop
  der(xg1) = (pin - xg1) / Ts;                                             // (3)
  xv = xg1;
  annotation(Documentation(info="<html>
<p>TG Type I (Bogodorova et al. 2016, eqs. 1-6) whose reference is corrected by a slow
integral load loop acting on the power measured through a filter T_f: the catalogue's
<code>load_controller_filtered</code> variant of <code>load_controller</code>.</p></html>",
    revisions="<html><ul><li>2026-11-25: first version.</li></ul></html>"));
end TGTypeILoadControlFiltered;
