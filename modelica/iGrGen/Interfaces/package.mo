within iGrGen;
package Interfaces "Signal connectors and partial blocks"
end Interfaces;
