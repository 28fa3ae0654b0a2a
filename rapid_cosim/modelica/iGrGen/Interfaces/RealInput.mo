within iGrGen.Interfaces;
connector RealInput "Real input signal"
  // Long form on purpose: pymoca drops the component of 'connector RealInput = input Real'.
  input Real signal;
  annotation(Documentation(info="<html>
<p>A real input signal. Written in the long form (a component <code>signal</code>) on purpose: pymoca drops the component of <code>connector RealInput = input Real</code>.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end RealInput;
