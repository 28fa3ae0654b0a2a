within iGrGen;
package Diagnosed "Test benches written by the discrepancy workflow: the base staged test with the effects it named, at their calibrated values"
end Diagnosed;
