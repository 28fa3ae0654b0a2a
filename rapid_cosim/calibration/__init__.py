"""Running estimations: start a run, resume it, re-run it from its archive alone.

``options`` (how a run is made), ``inputs`` (its problem and FMUs), ``replay`` (the
cache and comparison that make resume and re-run exact) and ``runs`` (the entry points).
"""

from .inputs import RunInputs, inputs_from_archive, inputs_from_configs, inputs_from_experiments, log_likelihood_for
from .options import RunOptions, parse_option_overrides
from .runs import SEARCHES, RerunReport, best_run, ensure_run, rerun, resume_run, start_run, summary_json

__all__ = ["RunInputs", "inputs_from_archive", "inputs_from_configs", "inputs_from_experiments", "log_likelihood_for",
           "RunOptions", "parse_option_overrides", "SEARCHES", "RerunReport", "best_run", "ensure_run", "rerun", "resume_run", "start_run",
           "summary_json"]
