within iGrGen;
package Interfaces "Signal connectors and partial blocks"
  annotation(Documentation(info="<html>
<p>Signal connectors and partial blocks, in the long form pymoca keeps.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end Interfaces;
