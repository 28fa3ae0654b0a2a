within iGrGen.Effects;
block Deadband "Intentional deadband on the frequency deviation (no-jump type)"
  extends Interfaces.SISO;
  parameter Types.Frequency db(min=0, max=1) = 0.015 "half-width of the band: deviations smaller than this are ignored";
  parameter Types.Frequency f_nom(min=1) = 50 "frequency base of the pu input";
  parameter Types.Frequency eps_db(min=1e-9, max=0.1) = 1e-4 "sharpness: smoothing width of the band edges";
  final parameter Types.PerUnit d = db / f_nom "half-width in pu";
  final parameter Types.PerUnit e = eps_db / f_nom "smoothing width in pu";
equation
  // u - clamp(u, -d, d), smoothed; exactly zero at u = 0.
  y.signal = u.signal + 0.5 * (sqrt((u.signal - d) ^ 2 + e ^ 2) - sqrt((u.signal + d) ^ 2 + e ^ 2));
  annotation(Documentation(info="<html>
<p>Intentional deadband of the no-jump type (IEEE PES-TR1 (2013), section on deadbands: outside the band the deviation acts reduced by the band). The clamp u - clamp(u, -d, d) is smoothed over eps_db: (sqrt((u - d)^2 + e^2) - sqrt((u + d)^2 + e^2)) / 2 + u, exactly zero at u = 0. db in Hz on the f_nom base; d and e are its pu values.</p></html>",
    revisions="<html><ul><li>2026-11-21: first version.</li><li>2026-11-24: units through iGrGen.Types; documentation with source and revisions.</li></ul></html>"));
end Deadband;
