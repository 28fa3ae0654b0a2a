within iGrGen.Governors;
block TGTypeI "TG Type I turbine-governor, equations (1)-(6) of Bogodorova et al."
  extends PartialTGTypeI;
initial equation
  der(xg1) = 0;
equation
  pin_star = p_ref + dw.signal / R;                                        // (1)
  der(xg1) = (pin - xg1) / Ts;                                             // (3)
  xv = xg1;
  annotation(Documentation(info="<html>
<p>TG Type I, equations (1)-(6) of T. Bogodorova, L. Vanfretti, K. Turitsyn, <i>Bayesian Parameter Estimation of Power System Primary Frequency Controls under Modeling Uncertainties</i> (2016), section II: TG Type I after F. Milano, <i>PSAT</i> documentation (2005): command p_ref + dw / R (1), limiter (6), governor lag Ts (3), servo Tc with transient gain T3 (4), reheat T5 with power fraction T4 (5), output (2). Initialised in steady state at p_ref.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end TGTypeI;
