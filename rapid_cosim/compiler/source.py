"""Where a run's models come from: one value passed down from the API to every stage.

A ``ModelSource`` names the Modelica package, the folder its FMUs are built into and the
compiler. The upper floors (identify, diagnose, the fleet, structure selection) take one
and hand it on, instead of three loose parameters that each stage had to keep in step.
It is a frozen value of paths and a word, so it travels to a worker process or a dask
worker as it is.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

from ..errors import ConfigError
from .builder import BuildOutcome, build_models, check_compiler, ensure_fmu, package_digest, resolve_models


@dataclass(frozen=True)
class ModelSource:
    """``package``: a Modelica package (None: ``$RAPID_COSIM_PACKAGE``, else the iGrGen
    shipped inside rapid_cosim); ``fmu_dir``: where its FMUs are built and found (None:
    ``$RAPID_COSIM_FMUS``, else the user's cache for this version); ``compiler``: one of
    :data:`~rapid_cosim.compiler.COMPILERS`."""

    package: Path | None = None
    fmu_dir: Path | None = None
    compiler: str = "auto"

    def __post_init__(self):
        for name in ("package", "fmu_dir"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, Path):
                object.__setattr__(self, name, Path(value))
        check_compiler(self.compiler)

    @property
    def package_path(self) -> Path:
        """The package, the default where none is named."""
        return resolve_models(self.package, self.fmu_dir)[0]

    @property
    def fmu_path(self) -> Path:
        """The FMU folder, the default where none is named."""
        return resolve_models(self.package, self.fmu_dir)[1]

    @property
    def users_package(self) -> bool:
        """Whether the package is the user's own (named, or ``$RAPID_COSIM_PACKAGE``), not
        the one shipped inside rapid_cosim: only the user's own may be written into."""
        return self.package is not None or bool(os.environ.get("RAPID_COSIM_PACKAGE"))

    def check(self) -> "ModelSource":
        """This source, once its package is found: a folder with a ``package.mo``, or a
        ``.mo`` file. A package named wrong is said at once, with where it was named, not
        as a missing file deep in a run (the shipped one is always there)."""
        if self.users_package:
            path = self.package_path
            if not ((path.is_dir() and (path / "package.mo").is_file()) or (path.is_file() and path.suffix == ".mo")):
                named = "--package (source.package)" if self.package is not None else "$RAPID_COSIM_PACKAGE"
                raise ConfigError(f"no Modelica package at {path}: name a folder with a package.mo, or a .mo file",
                                  None, named)
        return self

    def resolved(self) -> "ModelSource":
        """Absolute paths with the defaults filled in: what a worker in another folder, or
        with another environment, must be given."""
        return replace(self, package=self.package_path.resolve(), fmu_dir=self.fmu_path.resolve())

    def fmu(self, model: str) -> Path:
        """An up-to-date FMU of ``model`` (a class name, or a path to an .fmu)."""
        return ensure_fmu(model, package=self.package, fmu_dir=self.fmu_dir, compiler=self.compiler)

    def build(self, models: Sequence[str] | None, *, log: Callable[..., None] = lambda *_: None,
              force: bool = False) -> list[BuildOutcome]:
        """``models`` (None: every test bench of the package) compiled where they are out of
        date, or all with ``force``: once, before workers need them."""
        return build_models(None if models is None else list(models), package=self.package_path,
                            fmu_dir=self.fmu_path, compiler=self.compiler, force=force, log=log)

    def digest(self) -> str:
        """The package's sources' digest (what results made from its models depend on)."""
        return package_digest(self.package)
