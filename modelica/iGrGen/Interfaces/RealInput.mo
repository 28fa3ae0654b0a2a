within iGrGen.Interfaces;
connector RealInput "Real input signal"
  // Long form on purpose: pymoca drops the component of 'connector RealInput = input Real'.
  input Real signal;
end RealInput;
