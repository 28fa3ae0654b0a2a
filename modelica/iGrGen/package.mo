within;
package iGrGen "Turbine-governor models of the iGrGen plant for staged-test calibration"
  // Self-contained (no Modelica Standard Library). Per-unit quantities are on the machine
  // base; frequency deviations are injected in Hz and converted on a 50 Hz base.
  //
  // Written in what both build paths translate: no redeclare, when/pre/reinit/sample,
  // initial(), enumerations, delay() or nonlinear algebraic loops. Switching behaviour is
  // written with smooth functions whose sharpness parameter is documented where it
  // appears; relations on time become exact time events.
end iGrGen;
