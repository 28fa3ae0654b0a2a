within iGrGen.Governors;
block TGTypeIBacklash "TG Type I with backlash between the governor and the valve"
  extends PartialTGTypeI;
  parameter Types.PerUnit backlash(min=0, max=0.5) = 0.01 "total width of the play (pu of valve position)";
  parameter Types.Time T_bl(min=1e-4, max=10) = 0.05 "sharpness: time constant with which the valve follows once the play is taken up";
  parameter Types.PerUnit eps_bl(min=1e-9, max=0.1) = 1e-4 "sharpness: smoothing width of the dead zone edges (pu)";
  Effects.Backlash play(final backlash = backlash, final T_bl = T_bl, final eps_bl = eps_bl) "linkage play";
initial equation
  der(xg1) = 0;
equation
  pin_star = p_ref + dw.signal / R;                                        // (1)
  der(xg1) = (pin - xg1) / Ts;                                             // (3)
  play.u.signal = xg1;
  xv = play.y.signal;
  annotation(Documentation(info="<html>
<p>TG Type I (Bogodorova et al. 2016, eqs. 1-6) with play between the governor's output
xg1 and the valve position xv the turbine sees: the catalogue's <code>backlash</code>
effect.</p></html>",
    revisions="<html><ul><li>2026-11: the play is Effects.Backlash, shared with TGTypeIValveEffects.</li></ul></html>"));
end TGTypeIBacklash;
