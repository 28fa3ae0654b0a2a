within iGrGen;
package Diagnosed "Test benches written by the discrepancy workflow: the base staged test with the effects it named, at their calibrated values"
  annotation(Documentation(info="<html>
<p>Written by <code>rapid-cosim diagnose</code> (rapid_cosim.diagnose.catalogue): benches of
combinations of effects, effects on the recorded-frequency bench, and the named model at
its calibrated values. Each class documents what it was composed from.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: documentation.</li></ul></html>"));
end Diagnosed;
