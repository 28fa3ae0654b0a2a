within iGrGen.TestBenches;
model StagedTestBacklash "Staged test with backlash on the valve position"
  Sources.FrequencyStep src;
  Governors.TGTypeIBacklash gov;
  output Real pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
end StagedTestBacklash;
