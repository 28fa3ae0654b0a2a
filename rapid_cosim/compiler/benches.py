"""The test benches of the iGrGen package as a user chooses one (``rapid-cosim docs
benches``): each bench's name, what it is for (its description string), its inputs, with
the units their types carry, and its outputs. Read from the Modelica text, so the page is
the installed package's, whatever is installed."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from .builder import test_benches
from .modelica_source import class_index, load_package

_MODEL = re.compile(r'^\s*(?:partial\s+)?model\s+(\w+)\s*"([^"]*)"', re.M)
_PORT = re.compile(r'^\s*(input|output)\s+([\w.]+)\s+(\w+)[^;"]*(?:"([^"]*)")?\s*;', re.M)


@dataclass(frozen=True)
class Port:
    name: str
    kind: str  # input or output
    type: str  # as declared: Types.Frequency, Real, ...
    description: str


@dataclass(frozen=True)
class Bench:
    name: str  # iGrGen.TestBenches.StagedTest
    description: str
    ports: tuple[Port, ...]

    @property
    def inputs(self) -> tuple[Port, ...]:
        return tuple(p for p in self.ports if p.kind == "input")

    @property
    def outputs(self) -> tuple[Port, ...]:
        return tuple(p for p in self.ports if p.kind == "output")


def benches(package: Path) -> list[Bench]:
    """Every model of the package's ``TestBenches`` (:func:`.builder.test_benches`, what
    ``rapid-cosim build`` builds by default), in name order, read from its own lines."""
    source = load_package(package)
    index = class_index(source)
    lines = source.text.splitlines()
    out = []
    for name in sorted(test_benches(source)):
        extent = index[name]
        text = "\n".join(lines[extent.first_line - 1:extent.last_line])  # 1-based, inclusive
        head = _MODEL.search(text)
        if head is None:
            continue
        body = text[head.end():text.find("equation", head.end())]
        ports = tuple(Port(m.group(3), m.group(1), m.group(2), m.group(4) or "") for m in _PORT.finditer(body))
        out.append(Bench(name, head.group(2), ports))
    return out


def benches_page(package: Path) -> str:
    """The page, as markdown text."""
    lines = ["# Test benches", "",
             "The `model` of a config names one of these. A staged test's bench takes its step as parameters "
             "(`src.*`); a recorded event's takes the measured frequency as input `f_dev` (Hz), named in the "
             "config's `[inputs]`, and `rocof` where it has one (derived from `f_dev` when the recording has no "
             "ROCOF channel).", ""]
    for bench in benches(package):
        lines.append(f"## `{bench.name}`")
        lines += ["", bench.description, ""]
        for label, ports in (("inputs", bench.inputs), ("outputs", bench.outputs)):
            listed = "; ".join(f"`{p.name}` ({p.type.removeprefix('Types.')}{': ' + p.description if p.description else ''})"
                               for p in ports)
            lines.append(f"- {label}: {listed or 'none (a staged test: the step is a parameter)'}")
        lines.append("")
    return "\n".join(lines)
