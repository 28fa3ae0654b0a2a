within iGrGen.TestBenches;
model StagedTestTGOV1 "Staged test on the standard TGOV1 model: frequency step into the governor"
  Sources.FrequencyStep src;
  Governors.TGOV1 gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The staged test (Sources.FrequencyStep) into the standard TGOV1 (simple steam), Governors.TGOV1 (IEEE PES, <i>Dynamic Models for Turbine-Governors in Power System Studies</i>, PES-TR1 (2013)).</p></html>",
    revisions="<html><ul><li>2026-11-23: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end StagedTestTGOV1;
