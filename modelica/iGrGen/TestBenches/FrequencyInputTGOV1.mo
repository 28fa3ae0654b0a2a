within iGrGen.TestBenches;
model FrequencyInputTGOV1 "The standard TGOV1 model driven by a recorded frequency deviation given as an input"
  parameter Types.Frequency f_nom(min=1) = 50 "frequency base";
  input Types.Frequency f_dev "measured frequency minus nominal";
  Governors.TGOV1 gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  gov.dw.signal = -f_dev / f_nom;
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The standard TGOV1 (simple steam), Governors.TGOV1, driven by a recorded frequency deviation (input f_dev, Hz; the governor sees -f_dev / f_nom).</p></html>",
    revisions="<html><ul><li>2026-11-23: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end FrequencyInputTGOV1;
