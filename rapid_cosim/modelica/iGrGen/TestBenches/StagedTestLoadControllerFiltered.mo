within iGrGen.TestBenches;
model StagedTestLoadControllerFiltered "Staged test with a load controller acting on filtered power"
  Sources.FrequencyStep src;
  Governors.TGTypeILoadControlFiltered gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The staged test of TestBenches.StagedTest with Governors.TGTypeILoadControlFiltered: the catalogue's bench of the <code>load_controller_filtered</code> variant (rapid_cosim.diagnose.catalogue).</p></html>",
    revisions="<html><ul><li>2026-11-25: first version.</li></ul></html>"));
end StagedTestLoadControllerFiltered;
