within iGrGen.TestBenches;
model StagedTestDeadband "Staged test with an intentional deadband on the frequency deviation"
  Sources.FrequencyStep src;
  Effects.Deadband db;
  Governors.TGTypeI gov;
  output Real pm "mechanical power (pu)";
equation
  connect(src.y, db.u);
  connect(db.y, gov.dw);
  pm = gov.pm.signal;
end StagedTestDeadband;
