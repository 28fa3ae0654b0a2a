within iGrGen.TestBenches;
model StagedTest "Staged test on the base model: frequency step into TG Type I"
  Sources.FrequencyStep src;
  Governors.TGTypeI gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The paper's staged test: a frequency step (src.df at src.t_step, taken back at src.t_return) into TG Type I. The base bench of calibration and diagnosis.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end StagedTest;
