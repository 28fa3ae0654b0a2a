within iGrGen.TestBenches;
model StagedTestOutputLimit "Staged test with an output limit above the dispatch point"
  Sources.FrequencyStep src;
  Governors.TGTypeI gov;
  Effects.OutputLimit lim(p_ref = gov.p_ref);
  output Real pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  connect(gov.pm, lim.u);
  pm = lim.y.signal;
end StagedTestOutputLimit;
