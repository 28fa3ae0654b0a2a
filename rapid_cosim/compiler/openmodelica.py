"""Modelica -> FMU through OpenModelica (OMPython 4.x drives omc's buildModelFMU).

The package is loaded in place with ``loadFile`` on its ``package.mo``: OMPython 4.1's
``ModelicaSystem`` copies one file into its work folder, which breaks a package split
across files.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from ..errors import BuildError


def find_omc() -> str | None:
    """Path of omc through OPENMODELICAHOME, then PATH; None where it is absent."""
    home = os.environ.get("OPENMODELICAHOME")
    if home:
        candidate = Path(home) / "bin" / ("omc.exe" if os.name == "nt" else "omc")
        if candidate.exists():
            return str(candidate)
    return shutil.which("omc")


def omc_home(omc: str) -> str:
    return str(Path(omc).resolve().parents[1])


class OpenModelicaBuilder:
    """One omc session for a batch of builds (starting omc costs seconds)."""

    def __init__(self, package_mo: str | Path):
        omc = find_omc()
        if omc is None:
            raise BuildError("omc not found: set OPENMODELICAHOME or put omc on PATH, or use --compiler embedded")
        from OMPython import OMCSessionLocal  # imported late: it starts nothing until used

        self.session = OMCSessionLocal(omhome=omc_home(omc))
        self.package_mo = Path(package_mo).resolve()
        ok = self._send(f'loadFile("{self._escape(self.package_mo)}")')
        if ok is not True:
            raise BuildError(f"omc could not load {self.package_mo}: {self._errors()}")

    def _send(self, expr: str):
        try:
            return self.session.sendExpression(expr)
        except Exception as e:  # OMPython wraps omc's messages in its own exception types
            raise BuildError(f"omc failed on {expr}: {e}") from e

    def _errors(self) -> str:
        try:
            return str(self.session.sendExpression("getErrorString()")).strip()
        except Exception as e:
            return str(e)

    @staticmethod
    def _escape(path: Path) -> str:
        return str(path).replace("\\", "/").replace('"', '\\"')

    def build(self, class_name: str, fmu_path: str | Path) -> Path:
        fmu_path = Path(fmu_path)
        work = Path(tempfile.mkdtemp(prefix="rc_omc_"))
        try:
            self._send(f'cd("{self._escape(work)}")')
            prefix = class_name.replace(".", "_")
            result = self._send(
                f'buildModelFMU({class_name}, version="2.0", fmuType="me", fileNamePrefix="{prefix}")')
            if not result or not Path(str(result)).exists():
                raise BuildError(f"omc could not build {class_name}: {self._errors()}")
            fmu_path.parent.mkdir(parents=True, exist_ok=True)
            shutil.move(str(result), fmu_path)
            return fmu_path
        finally:
            shutil.rmtree(work, ignore_errors=True)

    def close(self) -> None:
        try:
            self.session.sendExpression("quit()")
        except Exception:  # omc may already be gone; nothing to clean up then
            pass
