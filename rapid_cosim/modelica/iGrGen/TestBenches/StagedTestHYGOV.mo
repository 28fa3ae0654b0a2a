within iGrGen.TestBenches;
model StagedTestHYGOV "Staged test on the standard HYGOV model: frequency step into the governor"
  Sources.FrequencyStep src;
  Governors.HYGOV gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The staged test (Sources.FrequencyStep) into the standard HYGOV (hydro with the water column), Governors.HYGOV (IEEE PES, <i>Dynamic Models for Turbine-Governors in Power System Studies</i>, PES-TR1 (2013)).</p></html>",
    revisions="<html><ul><li>2026-11-23: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end StagedTestHYGOV;
