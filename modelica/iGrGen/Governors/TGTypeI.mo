within iGrGen.Governors;
block TGTypeI "TG Type I turbine-governor, equations (1)-(6) of Bogodorova et al."
  extends PartialTGTypeI;
initial equation
  der(xg1) = 0;
equation
  pin_star = p_ref + dw.signal / R;                                        // (1)
  der(xg1) = (pin - xg1) / Ts;                                             // (3)
  xv = xg1;
end TGTypeI;
