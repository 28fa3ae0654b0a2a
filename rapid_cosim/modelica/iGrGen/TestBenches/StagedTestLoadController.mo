within iGrGen.TestBenches;
model StagedTestLoadController "Staged test with a slow load controller pulling power back to p_ref"
  Sources.FrequencyStep src;
  Governors.TGTypeILoadControl gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The staged test of TestBenches.StagedTest with Governors.TGTypeILoadControl: the catalogue's single-effect bench (rapid_cosim.diagnose.catalogue).</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end StagedTestLoadController;
