within iGrGen.Sources;
block FrequencyStep "Frequency deviation injected in a staged test, as the governor sees it"
  extends Interfaces.SO;
  parameter Types.Frequency df(min=-5, max=5) = -0.2 "injected deviation; negative mimics a frequency drop";
  parameter Types.Frequency f_nom(min=1) = 50 "frequency base";
  parameter Types.Time t_step(min=0) = 10 "time the deviation is applied";
  parameter Types.Time t_return(min=0) = 1e9 "time it is taken back (default: never)";
equation
  // y = w_ref - w in pu: a drop in frequency (df < 0) raises the governor's command.
  y.signal = if time >= t_step and time < t_return then -df / f_nom else 0;
  annotation(Documentation(info="<html><p>Both switching instants are exact time events.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end FrequencyStep;
