within iGrGen.Effects;
block Deadband "Intentional deadband on the frequency deviation (no-jump type)"
  extends Interfaces.SISO;
  parameter Real db(unit="Hz", min=0, max=1) = 0.015 "half-width of the band: deviations smaller than this are ignored";
  parameter Real f_nom(unit="Hz", min=1) = 50 "frequency base of the pu input";
  parameter Real eps_db(unit="Hz", min=1e-9, max=0.1) = 1e-4 "sharpness: smoothing width of the band edges";
  parameter Real d = db / f_nom "half-width in pu";
  parameter Real e = eps_db / f_nom "smoothing width in pu";
equation
  // u - clamp(u, -d, d), smoothed; exactly zero at u = 0.
  y.signal = u.signal + 0.5 * (sqrt((u.signal - d) ^ 2 + e ^ 2) - sqrt((u.signal + d) ^ 2 + e ^ 2));
end Deadband;
