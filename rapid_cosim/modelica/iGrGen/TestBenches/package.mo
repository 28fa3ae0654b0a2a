within iGrGen;
package TestBenches "Staged-test set-ups: a frequency-deviation source into a governor, top-level output pm"
  annotation(Documentation(info="<html>
<p>Staged-test set-ups (a FrequencyStep into a governor) and recorded-frequency benches (an input f_dev in Hz); each has a top-level output pm, the quantity the recorders measure.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end TestBenches;
