within iGrGen.Governors;
block TGTypeILoadControl "TG Type I under a slow load controller that pulls power back to p_ref"
  extends PartialTGTypeI;
  parameter Real K_lc(unit="1/s", min=0, max=10) = 0.005 "integral gain of the outer load loop (1/s); 1/K_lc is the withdrawal time constant";
  Real dp_lc(start=0, fixed=true) "load controller's correction of the reference (pu)";
initial equation
  der(xg1) = 0;
equation
  pin_star = p_ref + dp_lc + dw.signal / R;                                // (1) with the outer loop
  der(dp_lc) = K_lc * (p_ref - pm.signal);
  der(xg1) = (pin - xg1) / Ts;                                             // (3)
  xv = xg1;
end TGTypeILoadControl;
