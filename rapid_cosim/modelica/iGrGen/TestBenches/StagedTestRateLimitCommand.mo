within iGrGen.TestBenches;
model StagedTestRateLimitCommand "Staged test with rate limits on the governor's command"
  Sources.FrequencyStep src;
  Governors.TGTypeIRateLimitCommand gov;
  output Types.PerUnit pm "mechanical power (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
  annotation(Documentation(info="<html>
<p>The staged test of TestBenches.StagedTest with Governors.TGTypeIRateLimitCommand: the catalogue's bench of the <code>rate_limit_command</code> variant (rapid_cosim.diagnose.catalogue).</p></html>",
    revisions="<html><ul><li>2026-11-25: first version.</li></ul></html>"));
end StagedTestRateLimitCommand;
