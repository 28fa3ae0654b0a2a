within iGrGen.TestBenches;
model StagedTestHYGOV "Staged test on the standard HYGOV model: frequency step into the governor"
  Sources.FrequencyStep src;
  Governors.HYGOV gov;
  output Real pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
end StagedTestHYGOV;
