within iGrGen.TestBenches;
model StagedTestDelay "Staged test with a transport delay before the governor"
  Sources.FrequencyStep src;
  Effects.PadeDelay dly;
  Governors.TGTypeI gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, dly.u);
  connect(dly.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The staged test of TestBenches.StagedTest with Effects.PadeDelay on the frequency path: the catalogue's single-effect bench (rapid_cosim.diagnose.catalogue).</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end StagedTestDelay;
