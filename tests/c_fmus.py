"""FMUs written in C in ``tests/fmus/`` and compiled here, not made by rapid-cosim's
embedded compiler: the simulator must handle what other tools export.

:func:`build_c_fmu` compiles a model with the system C compiler against the FMI 2.0
headers fmpy ships and zips it with its model description. Options make the broken FMUs
a user may bring: a Co-Simulation-only FMU, or one without a binary for this platform.
"""

from __future__ import annotations

import os
import subprocess
import zipfile
from dataclasses import dataclass
from pathlib import Path

import fmpy

SOURCES = Path(__file__).parent / "fmus"


@dataclass(frozen=True)
class Var:
    name: str
    type: str  # Real, Integer, Boolean
    vr: int
    causality: str  # parameter, output, input, local
    variability: str = "continuous"
    start: float | None = None
    derivative: int | None = None  # 1-based index of the state variable
    min: float | None = None
    max: float | None = None


MODELS = {
    "BouncingBall": dict(guid="{8c4e810f-3df3-4a00-8276-176fa3c9f000}", n_states=2, n_indicators=1, variables=[
        Var("h", "Real", 0, "output"), Var("der(h)", "Real", 1, "local", derivative=1),
        Var("v", "Real", 2, "output"), Var("der(v)", "Real", 3, "local", derivative=3),
        Var("g", "Real", 4, "parameter", "fixed", 9.81), Var("e", "Real", 5, "parameter", "tunable", 0.7, min=0, max=1),
        Var("h0", "Real", 6, "parameter", "fixed", 1.0, min=0),
        Var("bounces", "Integer", 0, "output", "discrete"), Var("falling", "Boolean", 0, "output", "discrete"),
        Var("resting", "Boolean", 1, "output", "discrete")]),
    "Counter": dict(guid="{2a1b0c7e-4f55-4e1c-9d0a-5a1f00c0a001}", n_states=1, n_indicators=0, variables=[
        Var("x", "Real", 0, "output"), Var("der(x)", "Real", 1, "local", derivative=1),
        Var("period", "Real", 2, "parameter", "fixed", 1.0, min=0.01),
        Var("count", "Integer", 0, "output", "discrete"), Var("odd", "Boolean", 0, "output", "discrete")]),
    "DroopPlant": dict(guid="{6f0d1e2a-0b3c-4d5e-8f70-9a1b2c3d4e5f}", n_states=1, n_indicators=0, variables=[
        Var("p", "Real", 0, "output"), Var("der(p)", "Real", 1, "local", derivative=1),
        Var("R", "Real", 2, "parameter", "tunable", 0.05, min=0.01, max=0.2),
        Var("T", "Real", 3, "parameter", "tunable", 2.0, min=0.05, max=50.0),
        Var("p_ref", "Real", 4, "parameter", "tunable", 0.6, min=0.0, max=1.0),
        Var("dw", "Real", 5, "input", start=0.0)]),
}


def _xml(name: str, spec: dict, me: bool, cs: bool) -> str:
    rows, outputs, derivatives = [], [], []
    for index, v in enumerate(spec["variables"], start=1):
        attrs = {"name": v.name, "valueReference": v.vr, "causality": v.causality, "variability": v.variability}
        if v.causality == "output" and v.type == "Real":
            attrs["initial"] = "calculated"
        inner = {}
        if v.start is not None:
            inner["start"] = v.start
        if v.derivative is not None:
            inner["derivative"] = v.derivative
            derivatives.append(index)
        for bound in ("min", "max"):
            if getattr(v, bound) is not None:
                inner[bound] = getattr(v, bound)
        if v.causality == "output":
            outputs.append(index)
        a = " ".join(f'{k}="{val}"' for k, val in attrs.items())
        b = " ".join(f'{k}="{val}"' for k, val in inner.items())
        rows.append(f"    <ScalarVariable {a}><{v.type} {b}/></ScalarVariable>")
    interfaces = (f'  <ModelExchange modelIdentifier="{name}"/>\n' if me else "") + \
                 (f'  <CoSimulation modelIdentifier="{name}"/>\n' if cs else "")
    unknowns = lambda idx: "".join(f'<Unknown index="{i}"/>' for i in idx)  # noqa: E731
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{spec["guid"]}" '
            f'numberOfEventIndicators="{spec["n_indicators"]}">\n{interfaces}'
            f"  <ModelVariables>\n" + "\n".join(rows) + "\n  </ModelVariables>\n"
            f"  <ModelStructure><Outputs>{unknowns(outputs)}</Outputs>"
            f"<Derivatives>{unknowns(derivatives)}</Derivatives></ModelStructure>\n"
            f"</fmiModelDescription>\n")


def build_c_fmu(name: str, folder: Path, *, model_exchange: bool = True, co_simulation: bool = False,
                platform: str | None = None) -> Path:
    """``folder/<name>.fmu`` from ``tests/fmus/<name>.c``; ``platform`` names the binaries
    folder (default this machine's), so an FMU for another platform can be made."""
    spec = MODELS[name]
    folder.mkdir(parents=True, exist_ok=True)
    binary = folder / f"{name}{fmpy.sharedLibraryExtension}"
    include = Path(fmpy.__file__).parent / "c-code"
    cmd = [os.environ.get("CC", "cc"), "-std=c99", "-O1", "-fPIC", "-shared", f"-I{include}", f"-I{SOURCES}",
           str(SOURCES / f"{name}.c"), "-o", str(binary), "-lm"]
    subprocess.run(cmd, check=True, capture_output=True)
    suffix = "" if model_exchange and not co_simulation else ("-cs" if co_simulation and not model_exchange else "-both")
    plat = platform or fmpy.platform
    fmu = folder / f"{name}{suffix}{'' if plat == fmpy.platform else '-' + plat}.fmu"
    with zipfile.ZipFile(fmu, "w") as zf:
        zf.writestr("modelDescription.xml", _xml(name, spec, model_exchange, co_simulation))
        zf.write(binary, f"binaries/{plat}/{name}{fmpy.sharedLibraryExtension}")
    return fmu
