within iGrGen;
package Effects "Effects that staged tests reveal, and the valve-side blocks the governor variants are built from"
  annotation(Documentation(info="<html>
<p>Blocks for what staged tests reveal beyond TG Type I: on the frequency path (Deadband, TransportDelay; PadeDelay for a delay inside a loop), at the output (MeasurementLag, OutputLimit) and the valve-side blocks the governor variants are built from (RateLimitedLag, Backlash, LoadController). The diagnosis composes them into benches (rapid_cosim.diagnose.catalogue).</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end Effects;
