"""Modelica -> FMU: OpenModelica where omc exists, the embedded compiler elsewhere."""

from .builder import (COMPILERS, BuildOutcome, Manifest, build_models, default_fmu_dir, default_package, ensure_fmu,
                      fmu_path, package_digest, read_manifest, resolve_compiler, resolve_models, test_benches)

__all__ = ["COMPILERS", "BuildOutcome", "Manifest", "build_models", "default_fmu_dir", "default_package", "ensure_fmu",
           "fmu_path", "package_digest", "read_manifest", "resolve_compiler", "resolve_models", "test_benches"]
