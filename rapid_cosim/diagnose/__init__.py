"""The discrepancy workflow: where the calibrated base model and the measurements
disagree, which named physical effect explains it, and the model with that effect.

    catalogue   the named effects (Modelica benches, parameters, bounds, sizes that matter)
    candidates  one candidate (base + effects) calibrated jointly over the tests, archived
    selection   the information criterion (AR(1)-prewhitened BIC) and the verdict's rules
    features    residual analysis: whiteness windows and features that point at causes
    separate    the staged test that would tell two ambiguous candidates apart
    workflow    the whole: base, candidates, verdict, greedy second effect, model written
    study       synthetic campaigns with a known effect hidden, and the confusion matrix
"""

from .catalogue import CATALOGUE, NONE
from .workflow import DiagnoseOptions, Diagnosis, diagnose

__all__ = ["CATALOGUE", "NONE", "DiagnoseOptions", "Diagnosis", "diagnose"]
