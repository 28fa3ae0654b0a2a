within iGrGen.TestBenches;
model StagedTestBacklash "Staged test with backlash on the valve position"
  Sources.FrequencyStep src;
  Governors.TGTypeIBacklash gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The staged test of TestBenches.StagedTest with Governors.TGTypeIBacklash: the catalogue's single-effect bench (rapid_cosim.diagnose.catalogue).</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end StagedTestBacklash;
