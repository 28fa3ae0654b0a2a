within iGrGen.Interfaces;
connector RealOutput "Real output signal"
  output Real signal;
end RealOutput;
