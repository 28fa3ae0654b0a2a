"""FMUs written in C in ``tests/fmus/`` and compiled here, not made by rapid-cosim's
embedded compiler: the simulator must handle what other tools export.

:func:`build_c_fmu` compiles a model with the system C compiler against the FMI headers
fmpy ships (FMI 2.0, or 3.0 with ``fmi_version="3.0"``) and zips it with its model
description. One binary serves Model Exchange and Co-Simulation (``tests/fmus/
fmu_template.h``); the options say which interfaces the model description offers and
how its Co-Simulation interface presents itself (a variable communication step or a
fixed one, inputs interpolated or held), and make the broken FMUs a user may bring (one
without a binary for this platform).

The suite: every model in every kind (FMI 2.0 / 3.0 x ME / CS), see :data:`KINDS`.
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
    type: str  # Real, Integer, Boolean, String; Binary (FMI 3.0 only)
    vr: int  # per type, as the C model numbers them
    causality: str  # parameter, output, input, local
    variability: str = "continuous"
    start: float | None = None
    derivative: int | None = None  # 1-based index of the state variable
    min: float | None = None
    max: float | None = None


MODELS = {
    "BouncingBall": dict(guid="{8c4e810f-3df3-4a00-8276-176fa3c9f000}", n_states=2, n_indicators=1,
                         indicators=[0], variables=[
        Var("h", "Real", 0, "output"), Var("der(h)", "Real", 1, "local", derivative=1),
        Var("v", "Real", 2, "output"), Var("der(v)", "Real", 3, "local", derivative=3),
        Var("g", "Real", 4, "parameter", "fixed", 9.81), Var("e", "Real", 5, "parameter", "tunable", 0.7, min=0, max=1),
        Var("h0", "Real", 6, "parameter", "fixed", 1.0, min=0),
        Var("bounces", "Integer", 0, "output", "discrete"), Var("falling", "Boolean", 0, "output", "discrete"),
        Var("resting", "Boolean", 1, "output", "discrete")]),
    "Counter": dict(guid="{2a1b0c7e-4f55-4e1c-9d0a-5a1f00c0a001}", n_states=1, n_indicators=0, variables=[
        Var("x", "Real", 0, "output"), Var("der(x)", "Real", 1, "local", derivative=1),
        Var("period", "Real", 2, "parameter", "fixed", 1.0, min=0.01),
        Var("stop_at", "Real", 3, "parameter", "fixed", 1e9, min=0.0),
        Var("count", "Integer", 0, "output", "discrete"), Var("odd", "Boolean", 0, "output", "discrete"),
        Var("label", "String", 0, "output", "discrete"), Var("raw", "Binary", 0, "output", "discrete")]),
    "DroopPlant": dict(guid="{6f0d1e2a-0b3c-4d5e-8f70-9a1b2c3d4e5f}", n_states=1, n_indicators=0, variables=[
        Var("p", "Real", 0, "output"), Var("der(p)", "Real", 1, "local", derivative=1),
        Var("R", "Real", 2, "parameter", "tunable", 0.05, min=0.01, max=0.2),
        Var("T", "Real", 3, "parameter", "tunable", 2.0, min=0.05, max=50.0),
        Var("p_ref", "Real", 4, "parameter", "tunable", 0.6, min=0.0, max=1.0),
        Var("dw", "Real", 5, "input", start=0.0)]),
}

# The four kinds of the conformance suite: FMI version and interface.
KINDS = {"me2": ("2.0", "ME"), "cs2": ("2.0", "CS"), "me3": ("3.0", "ME"), "cs3": ("3.0", "CS")}

# FMI 3.0 value references are unique across types: the C template's offsets.
_VR3 = {"Real": 0, "Integer": 100, "Boolean": 200, "String": 300, "Binary": 400}
_TYPE3 = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "String": "String", "Binary": "Binary"}


def _fmt(value) -> str:
    return repr(float(value)) if isinstance(value, float) else str(value)


def _xml2(name: str, spec: dict, me: bool, cs: bool, interpolate: bool, variable_step: bool) -> str:
    rows, outputs, derivatives = [], [], []
    variables = [v for v in spec["variables"] if v.type != "Binary"]
    for index, v in enumerate(variables, start=1):
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
    cs_attrs = (f'canHandleVariableCommunicationStepSize="{str(variable_step).lower()}" '
                f'canInterpolateInputs="{str(interpolate).lower()}"')
    interfaces = (f'  <ModelExchange modelIdentifier="{name}"/>\n' if me else "") + \
                 (f'  <CoSimulation modelIdentifier="{name}" {cs_attrs}/>\n' if cs else "")
    unknowns = lambda idx: "".join(f'<Unknown index="{i}"/>' for i in idx)  # noqa: E731
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<fmiModelDescription fmiVersion="2.0" modelName="{name}" guid="{spec["guid"]}" '
            f'numberOfEventIndicators="{spec["n_indicators"]}">\n{interfaces}'
            f"  <ModelVariables>\n" + "\n".join(rows) + "\n  </ModelVariables>\n"
            f"  <ModelStructure><Outputs>{unknowns(outputs)}</Outputs>"
            f"<Derivatives>{unknowns(derivatives)}</Derivatives></ModelStructure>\n"
            f"</fmiModelDescription>\n")


def _xml3(name: str, spec: dict, me: bool, cs: bool, interpolate: bool, variable_step: bool) -> str:
    variables = spec["variables"]
    vr = {v.name: _VR3[v.type] + v.vr for v in variables}
    rows = ['    <Float64 name="time" valueReference="999" causality="independent" variability="continuous"/>']
    outputs, derivatives = [], []
    for v in variables:
        attrs = {"name": v.name, "valueReference": vr[v.name], "causality": v.causality}
        if v.type not in ("String", "Binary") or v.variability != "continuous":
            attrs["variability"] = v.variability
        if v.start is not None:
            attrs["start"] = _fmt(v.start)
        if v.derivative is not None:
            attrs["derivative"] = vr[variables[v.derivative - 1].name]
            derivatives.append(vr[v.name])
        for bound in ("min", "max"):
            if getattr(v, bound) is not None:
                attrs[bound] = _fmt(getattr(v, bound))
        if v.causality == "input" and cs and interpolate:
            attrs["intermediateUpdate"] = "true"
        if v.causality == "output":
            outputs.append(vr[v.name])
        a = " ".join(f'{k}="{val}"' for k, val in attrs.items())
        rows.append(f"    <{_TYPE3[v.type]} {a}/>")
    cs_attrs = (f'canHandleVariableCommunicationStepSize="{str(variable_step).lower()}" '
                f'providesIntermediateUpdate="{str(interpolate).lower()}"')
    interfaces = (f'  <ModelExchange modelIdentifier="{name}"/>\n' if me else "") + \
                 (f'  <CoSimulation modelIdentifier="{name}" {cs_attrs}/>\n' if cs else "")
    structure = "".join(f'<Output valueReference="{r}"/>' for r in outputs) + \
        "".join(f'<ContinuousStateDerivative valueReference="{r}"/>' for r in derivatives) + \
        "".join(f'<EventIndicator valueReference="{r}"/>' for r in spec.get("indicators", []))
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<fmiModelDescription fmiVersion="3.0" modelName="{name}" instantiationToken="{spec["guid"]}">\n'
            f"{interfaces}  <ModelVariables>\n" + "\n".join(rows) + "\n  </ModelVariables>\n"
            f"  <ModelStructure>{structure}</ModelStructure>\n</fmiModelDescription>\n")


def build_c_fmu(name: str, folder: Path, *, model_exchange: bool = True, co_simulation: bool = False,
                platform: str | None = None, fmi_version: str = "2.0", interpolate: bool = True,
                variable_step: bool = True) -> Path:
    """``folder/<name>[-fmi3][-cs|-both][-hold][-fixed][-<platform>].fmu`` from
    ``tests/fmus/<name>.c``. ``platform`` names the binaries folder (default this
    machine's), so an FMU for another platform can be made. For Co-Simulation,
    ``interpolate`` declares input interpolation (FMI 2.0 ``canInterpolateInputs``, FMI
    3.0 ``providesIntermediateUpdate``) and ``variable_step`` declares
    ``canHandleVariableCommunicationStepSize`` (without it the binary refuses a step
    other than its first)."""
    spec = MODELS[name]
    v3 = fmi_version == "3.0"
    folder.mkdir(parents=True, exist_ok=True)
    suffix = "" if model_exchange and not co_simulation else ("-cs" if co_simulation and not model_exchange else "-both")
    if co_simulation:
        suffix += ("" if interpolate else "-hold") + ("" if variable_step else "-fixed")
    plat = platform or (fmpy.platform_tuple if v3 else fmpy.platform)
    own = plat in (fmpy.platform, fmpy.platform_tuple)
    stem = f"{name}{'-fmi3' if v3 else ''}{suffix}{'' if own else '-' + plat}"
    binary = folder / f"{stem}{fmpy.sharedLibraryExtension}"
    include = Path(fmpy.__file__).parent / "c-code"
    flags = (["-DFMI3"] if v3 else []) + ([] if variable_step or not co_simulation else ["-DFIXED_STEP"])
    cmd = [os.environ.get("CC", "cc"), "-std=c99", "-O1", "-fPIC", "-shared", *flags, f"-I{include}",
           f"-I{SOURCES}", str(SOURCES / f"{name}.c"), "-o", str(binary), "-lm"]
    subprocess.run(cmd, check=True, capture_output=True)
    fmu = folder / f"{stem}.fmu"
    xml = (_xml3 if v3 else _xml2)(name, spec, model_exchange, co_simulation, interpolate, variable_step)
    with zipfile.ZipFile(fmu, "w") as zf:
        zf.writestr("modelDescription.xml", xml)
        zf.write(binary, f"binaries/{plat}/{name}{fmpy.sharedLibraryExtension}")
    return fmu


def build_kind(name: str, folder: Path, kind: str, **options) -> Path:
    """``name`` as one of :data:`KINDS` (Co-Simulation kinds without Model Exchange)."""
    version, interface = KINDS[kind]
    return build_c_fmu(name, folder, fmi_version=version, model_exchange=interface == "ME",
                       co_simulation=interface == "CS", **options)
