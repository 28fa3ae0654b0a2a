within iGrGen.TestBenches;
model FrequencyInputIEEEG1 "The standard IEEEG1 model driven by a recorded frequency deviation given as an input"
  parameter Real f_nom(unit="Hz", min=1) = 50 "frequency base";
  input Real f_dev(unit="Hz") "measured frequency minus nominal";
  Governors.IEEEG1 gov;
  output Real pm "mechanical power (pu)";
equation
  gov.dw.signal = -f_dev / f_nom;
  pm = gov.pm.signal;
end FrequencyInputIEEEG1;
