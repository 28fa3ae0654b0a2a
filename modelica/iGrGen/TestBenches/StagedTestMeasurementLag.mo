within iGrGen.TestBenches;
model StagedTestMeasurementLag "Staged test seen through a lagging, offset power transducer"
  Sources.FrequencyStep src;
  Governors.TGTypeI gov;
  Effects.MeasurementLag meas;
  output Real pm "measured mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  connect(gov.pm, meas.u);
  pm = meas.y.signal;
end StagedTestMeasurementLag;
