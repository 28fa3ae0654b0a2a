within iGrGen.Interfaces;
partial block SO "Single output"
  RealOutput y;
end SO;
