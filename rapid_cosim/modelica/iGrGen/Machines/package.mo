within iGrGen;
package Machines "The machine between the governor and the recorder: electrical power at the terminals"
  annotation(Documentation(info="<html>
<p>What a plant's recorder sees of the governor: electrical power at the terminals, the mechanical power less the rotor's inertial and damping power (SwingPower). The machine's speed is the recorded frequency, so the rotor's swing is given, not simulated: the network closes the loop in the plant, the recording stands in for it here.</p></html>",
    revisions="<html><ul><li>2026-11-25: first version (issue 26).</li></ul></html>"));
end Machines;
