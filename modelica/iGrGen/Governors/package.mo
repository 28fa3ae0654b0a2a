within iGrGen;
package Governors "TG Type I turbine-governor and its variants with valve-side effects"
end Governors;
