within iGrGen.TestBenches;
model StagedTestLoadController "Staged test with a slow load controller pulling power back to p_ref"
  Sources.FrequencyStep src;
  Governors.TGTypeILoadControl gov;
  output Real pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
end StagedTestLoadController;
