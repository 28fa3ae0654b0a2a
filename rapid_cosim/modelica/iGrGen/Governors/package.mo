within iGrGen;
package Governors "Turbine-governors: TG Type I and its variants with valve-side effects; the standard TGOV1, IEEEG1, GGOV1 and HYGOV"
  annotation(Documentation(info="<html>
<p>Turbine-governors: TG Type I (T. Bogodorova, L. Vanfretti, K. Turitsyn, <i>Bayesian Parameter Estimation of Power System Primary Frequency Controls under Modeling Uncertainties</i> (2016), section II: TG Type I after F. Milano, <i>PSAT</i> documentation (2005)) and its variants with valve-side effects, and the standard TGOV1, IEEEG1 and HYGOV (IEEE PES, <i>Dynamic Models for Turbine-Governors in Power System Studies</i>, PES-TR1 (2013); PSS/E Model Library). Each takes dw = w_ref - w (pu) and gives pm (pu), starting in steady state at its dispatch p_ref.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end Governors;
