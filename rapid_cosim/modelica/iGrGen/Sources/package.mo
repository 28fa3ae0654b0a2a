within iGrGen;
package Sources "Signals injected in staged tests"
  annotation(Documentation(info="<html>
<p>Signals injected in staged tests.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end Sources;
