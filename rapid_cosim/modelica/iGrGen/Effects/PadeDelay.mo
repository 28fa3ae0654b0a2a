within iGrGen.Effects;
block PadeDelay "Transport delay, second-order Pade approximant"
  extends Interfaces.SISO;
  parameter Types.Time T(min=1e-3, max=20) = 0.5 "delay";
  Real x1 "state of the Pade filter (pu s^2)";
  Real x2 "state of the Pade filter (pu s)";
initial equation
  der(x1) = 0;
  der(x2) = 0;
equation
  // (1 - sT/2 + (sT)^2/12) / (1 + sT/2 + (sT)^2/12) = 1 - (12/T) s / (s^2 + 6 s/T + 12/T^2)
  der(x1) = x2;
  der(x2) = u.signal - 12 / T ^ 2 * x1 - 6 / T * x2;
  y.signal = u.signal - 12 / T * x2;
  annotation(Documentation(info="<html><p>delay() has no counterpart in the embedded build path;
the approximant is exact in steady state and in phase to second order.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end PadeDelay;
