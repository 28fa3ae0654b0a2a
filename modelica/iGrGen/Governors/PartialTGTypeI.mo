within iGrGen.Governors;
partial block PartialTGTypeI "TG Type I (Milano 2005): parameters, limiter (6) and turbine (2), (4), (5)"
  parameter Real R(unit="1", min=0.001, max=1) = 0.05 "droop (pu)";
  parameter Real Ts(unit="s", min=0.001, max=100) = 0.5 "governor time constant";
  parameter Real Tc(unit="s", min=0.001, max=100) = 0.4 "servo time constant";
  parameter Real T3(unit="s", min=0, max=100) = 0.2 "transient gain time constant";
  parameter Real T4(unit="s", min=0, max=100) = 1.5 "power fraction time constant";
  parameter Real T5(unit="s", min=0.001, max=100) = 6.0 "reheat time constant";
  parameter Real pmax(unit="1", min=0, max=2) = 1.0 "maximum turbine output (pu)";
  parameter Real pmin(unit="1", min=0, max=2) = 0.0 "minimum turbine output (pu)";
  parameter Real p_ref(unit="1", min=0, max=2) = 0.6 "power reference, the dispatch (pu)";
  Interfaces.RealInput dw "speed deviation w_ref - w (pu)";
  Interfaces.RealOutput pm "mechanical power (pu)";
  Real pin_star "power command before the limiter (pu)";
  Real pin "limited power command (pu)";
  Real xg1 "governor state (pu)";
  Real xv "valve position the turbine sees; xg1 unless a subclass adds valve effects (pu)";
  Real xg2 "servo state (pu)";
  Real xg3 "reheat state (pu)";
initial equation
  der(xg2) = 0;
  der(xg3) = 0;
equation
  pin = min(max(pin_star, pmin), pmax);                                    // (6)
  der(xg2) = ((1 - T3 / Tc) * xv - xg2) / Tc;                              // (4)
  der(xg3) = ((1 - T4 / T5) * (xg2 + T3 / Tc * xv) - xg3) / T5;            // (5)
  pm.signal = xg3 + T4 / T5 * (xg2 + T3 / Tc * xv);                        // (2)
  annotation(Documentation(info="<html><p>Subclasses define the command (1) and the valve law (3).
The steady state at the start follows p_ref, so setting p_ref at run time re-initialises the states.</p></html>"));
end PartialTGTypeI;
