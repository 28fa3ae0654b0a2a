within iGrGen.Governors;
block TGTypeIBacklash "TG Type I with backlash between the governor and the valve"
  extends PartialTGTypeI;
  parameter Real backlash(unit="1", min=0, max=0.5) = 0.01 "total width of the play (pu of valve position)";
  parameter Real T_bl(unit="s", min=1e-4, max=10) = 0.05 "sharpness: time constant with which the valve follows once the play is taken up";
  parameter Real eps_bl(unit="1", min=1e-9, max=0.1) = 1e-4 "sharpness: smoothing width of the dead zone edges (pu)";
  Real gap "governor position minus valve position (pu)";
initial equation
  der(xg1) = 0;
  xv = xg1;
equation
  pin_star = p_ref + dw.signal / R;                                        // (1)
  der(xg1) = (pin - xg1) / Ts;                                             // (3)
  gap = xg1 - xv;
  // Dead zone of half-width backlash/2, smoothed with the exponential-tail softplus
  // eps*log(1 + exp(z/eps)) (written overflow-free): exactly zero at gap = 0, and, unlike
  // a sqrt smoothing, it does not let the valve creep through the play for long.
  T_bl * der(xv) = max(gap - backlash / 2, 0) + eps_bl * log(1 + exp(-abs(gap - backlash / 2) / eps_bl))
                 - max(-gap - backlash / 2, 0) - eps_bl * log(1 + exp(-abs(-gap - backlash / 2) / eps_bl));
end TGTypeIBacklash;
