within iGrGen.TestBenches;
model FrequencyInputGAST "The standard GAST model driven by a recorded frequency deviation given as an input"
  parameter Types.Frequency f_nom(min=1) = 50 "frequency base";
  input Types.Frequency f_dev "measured frequency minus nominal";
  input Types.FrequencyRate rocof "rate of change of the measured frequency (Hz/s)";
  Governors.GAST gov;
  Machines.SwingPower mach;
  output Types.PerUnit pm "mechanical power (pu)";
  output Types.PerUnit pe "electrical power at the terminals (pu)";
equation
  gov.dw.signal = -f_dev / f_nom;
  pm = gov.pm.signal;
  connect(gov.pm, mach.pm);
  mach.dw.signal = f_dev / f_nom;
  mach.dwdt.signal = rocof / f_nom;
  pe = mach.pe.signal;
  annotation(Documentation(info="<html>
<p>The standard GAST (simple gas turbine), Governors.GAST, driven by a recorded frequency deviation (input f_dev, Hz; the governor sees -f_dev / f_nom).</p>
<p>Electrical power at the terminals (output pe): the governor's output less the rotor's inertial and damping power, Machines.SwingPower, with the recorded frequency as the rotor's speed and its rate of change as input rocof (Hz/s). pm is what a staged test records, pe what a plant records during a grid event.</p></html>",
    revisions="<html><ul><li>2026-11-29: first version (issue 53).</li></ul></html>"));
end FrequencyInputGAST;
