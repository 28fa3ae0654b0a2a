within iGrGen;
package Governors "Turbine-governors: TG Type I and its variants with valve-side effects; the standard TGOV1, IEEEG1 and HYGOV"
end Governors;
