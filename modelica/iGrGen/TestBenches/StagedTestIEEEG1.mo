within iGrGen.TestBenches;
model StagedTestIEEEG1 "Staged test on the standard IEEEG1 model: frequency step into the governor"
  Sources.FrequencyStep src;
  Governors.IEEEG1 gov;
  output Real pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
end StagedTestIEEEG1;
