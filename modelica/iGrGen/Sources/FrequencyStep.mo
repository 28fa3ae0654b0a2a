within iGrGen.Sources;
block FrequencyStep "Frequency deviation injected in a staged test, as the governor sees it"
  extends Interfaces.SO;
  parameter Real df(unit="Hz", min=-5, max=5) = -0.2 "injected deviation; negative mimics a frequency drop";
  parameter Real f_nom(unit="Hz", min=1) = 50 "frequency base";
  parameter Real t_step(unit="s", min=0) = 10 "time the deviation is applied";
  parameter Real t_return(unit="s", min=0) = 1e9 "time it is taken back (default: never)";
equation
  // y = w_ref - w in pu: a drop in frequency (df < 0) raises the governor's command.
  y.signal = if time >= t_step and time < t_return then -df / f_nom else 0;
  annotation(Documentation(info="<html><p>Both switching instants are exact time events.</p></html>"));
end FrequencyStep;
