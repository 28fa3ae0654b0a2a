within iGrGen.TestBenches;
model StagedTestMeasurementLag "Staged test seen through a lagging, offset power transducer"
  Sources.FrequencyStep src;
  Governors.TGTypeI gov;
  Effects.MeasurementLag meas;
  output Types.PerUnit pm "measured mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  connect(gov.pm, meas.u);
  pm = meas.y.signal;
  annotation(Documentation(info="<html>
<p>The staged test of TestBenches.StagedTest with the output seen through Effects.MeasurementLag: the catalogue's single-effect bench (rapid_cosim.diagnose.catalogue).</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end StagedTestMeasurementLag;
