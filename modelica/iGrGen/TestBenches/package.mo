within iGrGen;
package TestBenches "Staged-test set-ups: a frequency-deviation source into a governor, top-level output pm"
end TestBenches;
