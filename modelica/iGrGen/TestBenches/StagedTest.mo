within iGrGen.TestBenches;
model StagedTest "Staged test on the base model: frequency step into TG Type I"
  Sources.FrequencyStep src;
  Governors.TGTypeI gov;
  output Real pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
end StagedTest;
