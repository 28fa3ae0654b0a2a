within iGrGen.TestBenches;
model StagedTestDelay "Staged test with a transport delay before the governor"
  Effects.TransportDelay dly;
  Sources.FrequencyStep src(t_delay = dly.T);
  Governors.TGTypeI gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The staged test of TestBenches.StagedTest with a transport delay dly.T on the frequency path
(Effects.TransportDelay: the injected step reaches the governor T later, exactly): the catalogue's
single-effect bench (rapid_cosim.diagnose.catalogue).</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li><li>2026-11-29: the exact delay (Effects.TransportDelay) instead of a second-order Pade approximant (issue 55).</li></ul></html>"));
end StagedTestDelay;
