within iGrGen.TestBenches;
model StagedTestOutputLimit "Staged test with an output limit above the dispatch point"
  Sources.FrequencyStep src;
  Governors.TGTypeI gov;
  Effects.OutputLimit lim(p_ref = gov.p_ref);
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  connect(gov.pm, lim.u);
  pm = lim.y.signal;
  annotation(Documentation(info="<html>
<p>The staged test of TestBenches.StagedTest with Effects.OutputLimit after the governor, counted from its dispatch: the catalogue's single-effect bench (rapid_cosim.diagnose.catalogue).</p></html>",
    revisions="<html><ul><li>2026-11-23: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end StagedTestOutputLimit;
