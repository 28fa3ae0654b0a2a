within iGrGen.Interfaces;
partial block SISO "Single input, single output"
  RealInput u;
  RealOutput y;
end SISO;
