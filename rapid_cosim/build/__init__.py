"""Modelica -> FMU: the OpenModelica backend where omc exists, the embedded one elsewhere."""

from .builder import (BACKENDS, BuildOutcome, Manifest, build_models, ensure_fmu, fmu_path, read_manifest,
                      resolve_backend, test_benches)

__all__ = ["BACKENDS", "BuildOutcome", "Manifest", "build_models", "ensure_fmu", "fmu_path", "read_manifest",
           "resolve_backend", "test_benches"]
