within iGrGen.Governors;
partial block PartialTGTypeI "TG Type I (Milano 2005): parameters, limiter (6) and turbine (2), (4), (5)"
  parameter Types.PerUnit R(min=0.001, max=1) = 0.05 "droop (pu)";
  parameter Types.Time Ts(min=0.001, max=100) = 0.5 "governor time constant";
  parameter Types.Time Tc(min=0.001, max=100) = 0.4 "servo time constant";
  parameter Types.Time T3(min=0, max=100) = 0.2 "transient gain time constant";
  parameter Types.Time T4(min=0, max=100) = 1.5 "power fraction time constant";
  parameter Types.Time T5(min=0.001, max=100) = 6.0 "reheat time constant";
  parameter Types.PerUnit pmax(min=0, max=2) = 1.0 "maximum turbine output (pu)";
  parameter Types.PerUnit pmin(min=0, max=2) = 0.0 "minimum turbine output (pu)";
  parameter Types.PerUnit p_ref(min=0, max=2) = 0.6 "power reference, the dispatch (pu)";
  Interfaces.RealInput dw "speed deviation w_ref - w (pu)";
  Interfaces.RealOutput pm "mechanical power (pu)";
  Types.PerUnit pin_star "power command before the limiter (pu)";
  Types.PerUnit pin "limited power command (pu)";
  Types.PerUnit xg1 "governor state (pu)";
  Types.PerUnit xv "valve position the turbine sees; xg1 unless a subclass adds valve effects (pu)";
  Types.PerUnit xg2 "servo state (pu)";
  Types.PerUnit xg3 "reheat state (pu)";
initial equation
  der(xg2) = 0;
  der(xg3) = 0;
equation
  pin = min(max(pin_star, pmin), pmax);                                    // (6)
  der(xg2) = ((1 - T3 / Tc) * xv - xg2) / Tc;                              // (4)
  der(xg3) = ((1 - T4 / T5) * (xg2 + T3 / Tc * xv) - xg3) / T5;            // (5)
  pm.signal = xg3 + T4 / T5 * (xg2 + T3 / Tc * xv);                        // (2)
  annotation(Documentation(info="<html><p>Subclasses define the command (1) and the valve law (3).
The steady state at the start follows p_ref, so setting p_ref at run time re-initialises the states.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end PartialTGTypeI;
