"""The layout as docs/architecture.md draws it: every import (lazy ones included) goes
down the data flow, and every module of the package is on the map."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "rapid_cosim"
DOC = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"

# top-level module or subpackage -> layer (a module may import from lower layers)
LAYERS = {
    "errors": 0, "version": 0, "search": 0, "compiler": 1, "simulator": 2, "data": 3, "noise": 3.5, "exchange": 3.7, "experiment": 4,
    "synthetic": 4.5,
    "problem": 5, "fitness": 6, "engine": 7, "objective": 7.5, "estimators": 8, "archive": 9,
    "calibration": 10, "staged": 11, "diagnose": 11, "identify": 11.5, "report": 12, "api": 13, "campaign": 13, "fleet": 13.5,
    "cli": 14,
}
LEAVES = {"errors", "search", "version"}


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path, path.relative_to(PACKAGE).with_suffix("").parts


def _imported(path: Path, parts: tuple[str, ...]) -> set[str]:
    """Top-level names of rapid_cosim that ``path`` imports (absolute or relative)."""
    tree = ast.parse(path.read_text())
    package = parts[:-1] if parts[-1] != "__init__" else parts[:-1]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(package[: len(package) - (node.level - 1)]) if node.level > 1 else list(package)
                target = base + (node.module.split(".") if node.module else [])
                if not target:  # "from . import x" at the top: x is a top-level module
                    found.update(alias.name for alias in node.names)
                else:
                    found.add(target[0])
            elif node.module and node.module.split(".")[0] == "rapid_cosim":
                rest = node.module.split(".")[1:]
                found.update([rest[0]] if rest else [a.name for a in node.names])
        elif isinstance(node, ast.Import):
            for alias in node.names:
                names = alias.name.split(".")
                if names[0] == "rapid_cosim" and len(names) > 1:
                    found.add(names[1])
    return found


def test_every_module_has_a_layer():
    missing = {parts[0] for _, parts in _modules() if parts[0] != "__init__"} - set(LAYERS)
    assert not missing, f"modules without a layer (add them to docs/architecture.md and LAYERS): {missing}"


@pytest.mark.parametrize("path,parts", list(_modules()), ids=lambda v: "/".join(v) if isinstance(v, tuple) else "")
def test_imports_follow_the_data_flow(path, parts):
    if parts == ("__init__",):  # the package's own top: the public API re-exported
        return
    own = parts[0]
    bad = []
    for name in _imported(path, parts):
        if name in ("__version__", own) or name in LEAVES:
            continue
        if name not in LAYERS:
            continue  # a name re-exported by the package top, checked where it is defined
        if LAYERS[name] >= LAYERS[own]:
            bad.append(f"{name} (layer {LAYERS[name]})")
    assert not bad, f"{'/'.join(parts)} (layer {LAYERS[own]}) imports against the flow: {', '.join(bad)}"


def test_leaves_import_nothing_from_the_package():
    for leaf in LEAVES:
        path = PACKAGE / f"{leaf}.py"
        assert _imported(path, (leaf,)) <= {"__version__"}, leaf


def test_the_map_names_every_module():
    text = DOC.read_text()
    missing = []
    for path, parts in _modules():
        if parts[-1] == "__init__":
            continue
        if f"`{parts[-1]}`" not in text and f"`{parts[0]}`" not in text and f"`{parts[0]}/`" not in text:
            missing.append("/".join(parts))
        elif len(parts) > 1 and f"`{parts[-1]}`" not in text:
            missing.append("/".join(parts))
    assert not missing, f"docs/architecture.md does not name: {', '.join(missing)}"


def test_the_check_sees_relative_absolute_and_lazy_imports(tmp_path):
    module = tmp_path / "m.py"
    module.write_text("from ...report.fits import x\nfrom ..inputs import y\nimport rapid_cosim.cli\n"
                      "def f():\n    from ...api import calibrate\n    from rapid_cosim import campaign\n")
    assert _imported(module, ("simulator", "sub", "m")) == {"report", "simulator", "cli", "api", "campaign"}


def test_the_api_functions_stay_functions_once_their_subpackages_are_imported():
    """rc.diagnose and rc.identify share their names with subpackages, which the functions
    import when called: a first import of a subpackage binds its name on the package, and
    a second rc.identify(...) failed with "'module' object is not callable"."""
    import subprocess
    import sys

    code = ("import rapid_cosim as rc, rapid_cosim.diagnose, rapid_cosim.identify, inspect; "
            "print(inspect.isfunction(rc.diagnose), inspect.isfunction(rc.identify))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["True", "True"]
