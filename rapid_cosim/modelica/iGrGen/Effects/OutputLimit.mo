within iGrGen.Effects;
block OutputLimit "Output limit above the dispatch point (temperature-limit control near MCR)"
  extends Interfaces.SISO;
  parameter Types.PerUnit p_ref(min=0, max=1.2) = 0.6 "dispatch point the headroom is counted from (pu)";
  parameter Types.PerUnit headroom(min=1e-3, max=1) = 0.05 "largest rise of the output above p_ref (pu)";
  parameter Types.PerUnit eps_lim(min=1e-9, max=0.1) = 1e-3 "sharpness: width of the rounded corner of the smooth limit (pu)";
  final parameter Types.PerUnit z0 = -headroom "distance of the dispatch point from the limit (pu)";
equation
  // u - max(u - (p_ref + headroom), 0), smoothed; the correction vanishes at u = p_ref
  // exactly, so the steady state at dispatch is unchanged.
  y.signal = u.signal
    - 0.5 * (u.signal - p_ref - headroom + sqrt((u.signal - p_ref - headroom) ^ 2 + eps_lim ^ 2))
    + 0.5 * (z0 + sqrt(z0 ^ 2 + eps_lim ^ 2));
  annotation(Documentation(info="<html><p>Gas turbines near their Maximum Continuous Rating enter
temperature-limit control (section 3 of the paper): the exhaust temperature, not the governor,
sets the fuel, and the unit stops short of what droop asks for. Modelled at the output as
y = u - max(u - (p_ref + headroom), 0), with the corner rounded over eps_lim (a softplus),
so that gradients exist at the limit; below it y = u exactly at the dispatch point and
within eps_lim^2 / (4 |u - p_ref - headroom|) elsewhere.</p>
<p>Units: pu on the machine base. Range of headroom: 0.001 to 1 pu.</p></html>",
    revisions="<html><ul><li>2026-11-23: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end OutputLimit;
