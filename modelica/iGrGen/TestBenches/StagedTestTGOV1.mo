within iGrGen.TestBenches;
model StagedTestTGOV1 "Staged test on the standard TGOV1 model: frequency step into the governor"
  Sources.FrequencyStep src;
  Governors.TGOV1 gov;
  output Real pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
end StagedTestTGOV1;
