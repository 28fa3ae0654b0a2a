within iGrGen.TestBenches;
model StagedTestDeadband "Staged test with an intentional deadband on the frequency deviation"
  Sources.FrequencyStep src;
  Effects.Deadband db(f_nom = src.f_nom) "its band on the test's frequency base";
  Governors.TGTypeI gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, db.u);
  connect(db.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The staged test of TestBenches.StagedTest with Effects.Deadband on the frequency path: the catalogue's single-effect bench (rapid_cosim.diagnose.catalogue).</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end StagedTestDeadband;
