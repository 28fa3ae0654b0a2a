within iGrGen.Effects;
block LoadController "Slow outer load loop: integrates the power error into a correction of the reference"
  extends Interfaces.SISO;
  parameter Types.PerUnitRate K_lc(min=0, max=10) = 0.005 "integral gain (1/s); 1/K_lc is the withdrawal time constant";
  parameter Types.PerUnit p_ref(min=0, max=2) = 0.6 "power set-point the loop holds (pu)";
  Types.PerUnit dp(start=0, fixed=true) "correction of the governor's reference (pu)";
equation
  der(dp) = K_lc * (p_ref - u.signal);
  y.signal = dp;
  annotation(Documentation(info="<html>
<p>A plant's load (MW) controller in its simplest form: an integrator of the set-point
error, added to the governor's reference, that drags the power back after a frequency
step. Input: the power (pu); output: the reference correction (pu), zero at the start.</p></html>",
    revisions="<html><ul><li>2026-11: one block for TGTypeILoadControl and TGTypeIValveEffects.</li></ul></html>"));
end LoadController;
