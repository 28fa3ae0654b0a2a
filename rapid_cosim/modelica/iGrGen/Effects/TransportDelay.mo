within iGrGen.Effects;
block TransportDelay "Transport delay of a known input: exact, by moving the input in time"
  parameter Types.Time T(min=0, max=20) = 0.5 "delay";
  annotation(Documentation(info="<html>
<p>A transport delay between the frequency the plant's governor sees and the one recorded
or injected: y(t) = u(t - T), the input held at its first value before it starts. The input
is known (a staged test's injected step, a recorded event's frequency), so the delay is
exact with no state of its own: the block holds T, and what reads the input applies it.
A staged test's source moves its switching instants by T
(<code>Sources.FrequencyStep(t_delay = dly.T)</code>: exact time events); a recorded-frequency
bench reads the input <code>f_dev_delayed</code>, which the runner fills with the recording
at t - T, per parameter set (rapid_cosim.simulator.delayed).</p>
<p>Where the delayed signal is not known in advance (a delay inside a feedback loop),
Effects.PadeDelay approximates it; the discrepancy workflow's benches do not need it.</p>
<p>Range: 0 to 20 s. Source: a pure delay, e^(-sT); IEEE PES-TR1 (2013) lists transport
delays of the speed signal and of the governor's command among the dynamics a staged test
reveals.</p></html>",
    revisions="<html><ul><li>2026-11-29: first version; replaces the second-order Pade approximant on the catalogue's benches, whose inverse response on a step grew with the step (issue 55).</li></ul></html>"));
end TransportDelay;
