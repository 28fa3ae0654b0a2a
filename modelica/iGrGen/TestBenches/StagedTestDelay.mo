within iGrGen.TestBenches;
model StagedTestDelay "Staged test with a transport delay before the governor"
  Sources.FrequencyStep src;
  Effects.PadeDelay dly;
  Governors.TGTypeI gov;
  output Real pm "mechanical power (pu)";
equation
  connect(src.y, dly.u);
  connect(dly.y, gov.dw);
  pm = gov.pm.signal;
end StagedTestDelay;
