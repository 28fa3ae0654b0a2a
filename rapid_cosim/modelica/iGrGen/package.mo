within;
package iGrGen "Turbine-governor models of the iGrGen plant for staged-test calibration"
  // Self-contained (no Modelica Standard Library). Per-unit quantities are on the machine
  // base; frequency deviations are injected in Hz and converted on a 50 Hz base.
  //
  // Written in what both build paths translate: no redeclare, when/pre/reinit/sample,
  // initial(), enumerations, delay() or nonlinear algebraic loops. Switching behaviour is
  // written with smooth functions whose sharpness parameter is documented where it
  // appears; relations on time become exact time events.
  annotation(Documentation(info="<html>
<p>The iGrGen plant's turbine-governor models for calibration against staged tests and recorded disturbances: the paper's TG Type I (T. Bogodorova, L. Vanfretti, K. Turitsyn, <i>Bayesian Parameter Estimation of Power System Primary Frequency Controls under Modeling Uncertainties</i> (2016), section II: TG Type I after F. Milano, <i>PSAT</i> documentation (2005)), its valve-side variants, the standard TGOV1, IEEEG1 and HYGOV (IEEE PES, <i>Dynamic Models for Turbine-Governors in Power System Studies</i>, PES-TR1 (2013)), effects, and test benches whose top-level output is pm.</p><p>Self-contained (no Modelica Standard Library). Per-unit quantities are on the machine base; frequency deviations are injected in Hz and converted on the f_nom base. Written in what both build paths translate: no redeclare, when/pre/reinit/sample, initial(), enumerations, delay() or nonlinear algebraic loops. Switching behaviour is written with smooth functions whose sharpness parameter is documented where it appears; relations on time become exact time events.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end iGrGen;
