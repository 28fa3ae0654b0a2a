within iGrGen.Effects;
block MeasurementLag "First-order lag and constant offset of the power transducer"
  extends Interfaces.SISO;
  parameter Types.Time T(min=1e-3, max=20) = 0.5 "transducer time constant";
  parameter Types.PerUnit offset(min=-0.1, max=0.1) = 0 "constant offset added by the transducer (pu)";
  Types.PerUnit x "lagged signal (pu)";
initial equation
  der(x) = 0;
equation
  T * der(x) = u.signal - x;
  y.signal = x + offset;
  annotation(Documentation(info="<html>
<p>The power transducer as a first-order lag T with a constant offset: what a recorder of pm sees. Starts at rest.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end MeasurementLag;
