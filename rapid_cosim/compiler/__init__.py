"""Modelica -> FMU: OpenModelica where omc exists, the embedded compiler elsewhere."""

from .builder import (COMPILERS, BuildOutcome, Manifest, build_models, ensure_fmu, fmu_path, read_manifest,
                      resolve_compiler, test_benches)

__all__ = ["COMPILERS", "BuildOutcome", "Manifest", "build_models", "ensure_fmu", "fmu_path", "read_manifest",
           "resolve_compiler", "test_benches"]
