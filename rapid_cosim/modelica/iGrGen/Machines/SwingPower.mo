within iGrGen.Machines;
block SwingPower "Electrical power at the terminals: mechanical power less the rotor's inertial and damping power (swing equation)"
  parameter Types.Time H(min=0.5, max=15) = 5.0 "inertia constant on the machine base: kinetic energy at rated speed / rated MVA";
  parameter Types.PerUnit D(min=0, max=5) = 0.0 "damping on the machine base (pu power per pu speed)";
  parameter Types.PerUnit torque(min=0, max=1) = 0.0 "1: the governor's output is the turbine's torque (P_m = w pm), 0: its power (PSS/E's PMECH)";
  Interfaces.RealInput pm "the governor's output (pu)";
  Interfaces.RealInput dw "speed deviation w - 1, the recorded frequency's (f - f_nom) / f_nom (pu)";
  Interfaces.RealInput dwdt "rotor acceleration dw/dt, the recorded ROCOF / f_nom (pu/s)";
  Interfaces.RealOutput pe "electrical power at the terminals (pu)";
  Types.PerUnit w "rotor speed (pu)";
equation
  w = 1 + dw.signal;
  pe.signal = (1 + torque * dw.signal) * pm.signal - w * (2 * H * dwdt.signal + D * dw.signal);
  annotation(Documentation(info="<html>
<p>Source: the swing equation in per unit, P. Kundur, <i>Power System Stability and Control</i>
(McGraw-Hill, 1994), section 3.9 (equations of motion): 2 H dw/dt = T_m - T_e - K_D (w - 1), torques
on the machine base, H the inertia constant in s (the stored energy at rated speed over the MVA rating;
Kundur's typical values run from 2 s for hydro units to 10 s for four-pole thermal units). The air-gap power is P_e = w T_e, so</p>
<pre>  P_e = P_m - w (2 H dw/dt + D (w - 1)),   P_m = pm (1 + torque (w - 1))</pre>
<p>with pm the governor's output: a power (torque = 0, PSS/E's PMECH, the machine dividing by speed)
or a torque (torque = 1, P_m = w pm). To first
order both are P_m - 2 H dw/dt - D (w - 1); they differ by pm (w - 1), 0.3 % of rating for 0.2 Hz at
0.8 pu, which a fit of the droop sees. ANDES 2.0's GENROU (the plant of the electrical-power test
events) has neither speed factor: its recorded P_e is tm - 2 H dw/dt within 5e-6 pu, tm being the
governor's output, so torque = 0 is its convention, off from it by (w - 1) 2 H dw/dt (3 to 6e-4 pu
in an event's first second, which shortens a fitted fast lag by 0.5 to 3 %).</p>
<p>The speed is the recorded frequency (dw = (f - f_nom) / f_nom; dwdt = ROCOF / f_nom): the network that swings the rotor in
the plant is the recording here, so the block is algebraic and adds no state. Not modelled: the
stator's copper loss (r_a I^2, a near-constant offset, profiled with the transducer's), and the
difference between the rotor's speed and the terminal bus frequency a PMU measures (the rotor
angle's swing against the bus, within the inter-area modes).</p>
<p>Ranges: H 0.5 to 15 s (aero-derivative gas turbines to large four-pole units with their
shaft line); D 0 to 5 pu (Kundur's K_D; 0 where the damper windings are modelled in the
machine, as GENROU's). Units: pu on the machine base, s.</p></html>",
    revisions="<html><ul><li>2026-11-25: first version (issue 26).</li><li>2026-11-25: ANDES's convention measured (torque = 0, no speed factor).</li></ul></html>"));
end SwingPower;
