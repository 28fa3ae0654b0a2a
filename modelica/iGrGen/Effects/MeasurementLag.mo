within iGrGen.Effects;
block MeasurementLag "First-order lag and constant offset of the power transducer"
  extends Interfaces.SISO;
  parameter Real T(unit="s", min=1e-3, max=20) = 0.5 "transducer time constant";
  parameter Real offset(unit="1", min=-0.1, max=0.1) = 0 "constant offset added by the transducer (pu)";
  Real x "lagged signal (pu)";
initial equation
  der(x) = 0;
equation
  T * der(x) = u.signal - x;
  y.signal = x + offset;
end MeasurementLag;
