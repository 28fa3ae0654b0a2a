within iGrGen.TestBenches;
model StagedTestGGOV1 "Staged test on the standard GGOV1 model: frequency step into the governor"
  Sources.FrequencyStep src;
  Governors.GGOV1 gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
  connect(gov.pm, gov.pelec);
  annotation(Documentation(info="<html>
<p>The staged test (Sources.FrequencyStep) into the standard GGOV1 (general gas turbine), Governors.GGOV1 (IEEE PES, <i>Dynamic Models for Turbine-Governors in Power System Studies</i>, PES-TR1 (2013)). On the stiff grid of a staged test the electrical power the governor reads (pelec) is its mechanical power.</p></html>",
    revisions="<html><ul><li>2026-11-24: first version.</li><li>2026-11-25: pelec fed the mechanical power (issue 26).</li></ul></html>"));
end StagedTestGGOV1;
