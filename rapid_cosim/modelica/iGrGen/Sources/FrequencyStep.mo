within iGrGen.Sources;
block FrequencyStep "Frequency deviation injected in a staged test, as the governor sees it"
  extends Interfaces.SO;
  parameter Types.Frequency df(min=-5, max=5) = -0.2 "injected deviation; negative mimics a frequency drop";
  parameter Types.Frequency f_nom(min=1) = 50 "frequency base";
  parameter Types.Time t_step(min=0) = 10 "time the deviation is applied";
  parameter Types.Time t_return(min=0) = 1e9 "time it is taken back (default: never)";
  parameter Types.Time t_delay(min=0, max=20) = 0 "transport delay on the way to the governor: the deviation reaches it this much later";
equation
  // y = w_ref - w in pu: a drop in frequency (df < 0) raises the governor's command.
  y.signal = if time >= t_step + t_delay and time < t_return + t_delay then -df / f_nom else 0;
  annotation(Documentation(info="<html><p>Both switching instants are exact time events. A transport
delay t_delay (Effects.TransportDelay's T) moves them both: the delayed step is exact.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li><li>2026-11-29: t_delay, the exact transport delay (issue 55).</li></ul></html>"));
end FrequencyStep;
