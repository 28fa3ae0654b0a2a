within iGrGen.Effects;
block Backlash "Play between a driving position and the driven one (governor linkage to valve)"
  extends Interfaces.SISO;
  parameter Types.PerUnit backlash(min=0, max=0.5) = 0.01 "total width of the play (pu of position)";
  parameter Types.Time T_bl(min=1e-4, max=10) = 0.05 "sharpness: time constant with which the output follows once the play is taken up";
  parameter Types.PerUnit eps_bl(min=1e-9, max=0.1) = 1e-4 "sharpness: smoothing width of the dead zone edges (pu)";
  Types.PerUnit gap "input minus output position (pu)";
  Types.PerUnit x "output position, the state (pu)";
initial equation
  x = u.signal;
equation
  gap = u.signal - x;
  // Dead zone of half-width backlash/2, smoothed with the exponential-tail softplus
  // eps*log(1 + exp(z/eps)) (written overflow-free): exactly zero at gap = 0, and, unlike
  // a sqrt smoothing, it does not let the output creep through the play for long.
  T_bl * der(x) = max(gap - backlash / 2, 0) + eps_bl * log(1 + exp(-abs(gap - backlash / 2) / eps_bl))
                - max(-gap - backlash / 2, 0) - eps_bl * log(1 + exp(-abs(-gap - backlash / 2) / eps_bl));
  y.signal = x;
  annotation(Documentation(info="<html>
<p>Backlash (mechanical play) as a fast follower through a dead zone: the output moves
only once the input has crossed half the play, then follows with T_bl. A true backlash
has a discontinuous derivative at reversal; this form has no state events, and its
sharpness (T_bl, eps_bl) is fixed in the catalogue. Starts at rest, centred (x = u).</p></html>",
    revisions="<html><ul><li>2026-11: one block for TGTypeIBacklash and TGTypeIValveEffects, which each held a copy of these equations.</li></ul></html>"));
end Backlash;
