within iGrGen.TestBenches;
model StagedTestRateLimit "Staged test with valve rate limits (opening and closing)"
  Sources.FrequencyStep src;
  Governors.TGTypeIRateLimit gov;
  output Real pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
end StagedTestRateLimit;
