within iGrGen;
package Sources "Signals injected in staged tests"
end Sources;
