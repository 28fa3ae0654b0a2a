within iGrGen.Interfaces;
partial block SO "Single output"
  RealOutput y;
  annotation(Documentation(info="<html>
<p>A block with one output y.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end SO;
