within iGrGen;
package Types "Physical types: each unit written once"
  type PerUnit = Real(unit="1");
  type Time = Real(unit="s");
  type Frequency = Real(unit="Hz");
  type PerUnitRate = Real(unit="1/s");
  type FrequencyRate = Real(unit="Hz/s");
  annotation(Documentation(info="<html>
<p>Per-unit quantities are on the machine base (power, valve position, speed deviation);
PerUnitRate is a per-unit quantity per second (valve speeds, integral gains); FrequencyRate is a rate of change of frequency (ROCOF, Hz/s). Types carry
no description: a declaration's own comment describes it.</p></html>",
    revisions="<html><ul><li>2026-11: introduced, replacing Real(unit=...) written at every declaration.</li><li>2026-11-25: FrequencyRate (ROCOF).</li></ul></html>"));
end Types;
