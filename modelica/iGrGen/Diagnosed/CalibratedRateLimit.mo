within iGrGen.Diagnosed;
model CalibratedRateLimit "base staged test with rate_limit, calibrated on test1, test2, test3, test5, test6, test7, test9, test10 by rapid-cosim diagnose"
  Sources.FrequencyStep src;
  Governors.TGTypeIRateLimit gov(R = 0.05503364355, Ts = 1.446135051, rate_open = 0.01009219337, rate_close = 0.02969753743);
  output Real pm "mechanical power as recorded (pu)";
equation
  connect(src.y, gov.dw);
  pm = gov.pm.signal;
end CalibratedRateLimit;
