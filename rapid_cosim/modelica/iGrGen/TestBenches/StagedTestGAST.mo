within iGrGen.TestBenches;
model StagedTestGAST "Staged test on the standard GAST model: frequency step into the governor"
  Sources.FrequencyStep src;
  Governors.GAST gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The staged test (Sources.FrequencyStep) into the standard GAST (simple gas turbine), Governors.GAST (IEEE PES, <i>Dynamic Models for Turbine-Governors in Power System Studies</i>, PES-TR1 (2013), ch. 3).</p></html>",
    revisions="<html><ul><li>2026-11-29: first version (issue 53).</li></ul></html>"));
end StagedTestGAST;
