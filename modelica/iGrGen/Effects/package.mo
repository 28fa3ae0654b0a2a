within iGrGen;
package Effects "Signal-path effects that staged tests reveal (valve-side effects are governor variants)"
end Effects;
