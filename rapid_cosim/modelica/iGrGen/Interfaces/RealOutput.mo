within iGrGen.Interfaces;
connector RealOutput "Real output signal"
  output Real signal;
  annotation(Documentation(info="<html>
<p>A real output signal, in the long form of RealInput.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end RealOutput;
