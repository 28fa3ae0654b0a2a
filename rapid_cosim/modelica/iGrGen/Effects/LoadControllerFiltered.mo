within iGrGen.Effects;
block LoadControllerFiltered "Slow outer load loop acting on the power measured through a filter"
  extends Interfaces.SISO;
  parameter Types.PerUnitRate K_lc(min=0, max=10) = 0.005 "integral gain (1/s); 1/K_lc is the withdrawal time constant";
  parameter Types.Time T_f(min=0.01, max=1000) = 10 "time constant of the filter on the loop's power measurement";
  parameter Types.PerUnit p_ref(min=0, max=2) = 0.6 "power set-point the loop holds (pu)";
  Types.PerUnit p_f "the loop's filtered power measurement (pu)";
  Types.PerUnit dp(start=0, fixed=true) "correction of the governor's reference (pu)";
initial equation
  p_f = p_ref;
equation
  T_f * der(p_f) = u.signal - p_f;
  der(dp) = K_lc * (p_ref - p_f);
  y.signal = dp;
  annotation(Documentation(info="<html>
<p>The load controller of Effects.LoadController, whose power measurement passes through
a first-order filter T_f first (a plant's MW controller commonly filters its measurement
over seconds to tens of seconds). Input: the power (pu); output: the reference
correction (pu), zero at the start. Against the unfiltered loop the withdrawal starts
late and rounded, which a freed reheat constant T5 can partly imitate: the diagnosis
tries this variant before it blames the documentation (rapid_cosim.diagnose.variants).
T_f to 0 gives Effects.LoadController.</p></html>",
    revisions="<html><ul><li>2026-11-25: first version.</li></ul></html>"));
end LoadControllerFiltered;
