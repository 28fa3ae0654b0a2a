"""The layout as docs/architecture.md draws it: every import (lazy ones included) goes
down the data flow, and every module of the package is on the map."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "rapid_cosim"
DOC = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"

# top-level module or subpackage (a room) -> layer (a room may import from lower layers)
LAYERS = {
    "errors": 0, "version": 0, "progress": 0, "compiler": 1, "simulator": 2, "data": 3, "noise": 3.5, "exchange": 3.7,
    "experiment": 4, "fitting": 5, "estimators": 8, "archive": 9, "calibration": 10, "validation": 10.5, "diagnose": 11,
    "structures": 11.3, "identify": 11.5, "report": 12, "examples": 12.5, "api": 13, "fleet": 13.5, "check": 13.7, "cli": 14,
}
LEAVES = {"errors", "version", "progress"}
# the modules that may sit at the package root: its face (__init__, api), errors, the version, progress
ROOT_MODULES = {"__init__", "api", "errors", "version", "progress"}


FACE = "<the package's face>"  # rapid_cosim/__init__.py, which imports everything


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
                if not target:  # "from . import x" at the top: x is a top-level module, or a name of the face
                    found.update(alias.name if (PACKAGE / alias.name).is_dir() or (PACKAGE / f"{alias.name}.py").exists()
                                 else FACE for alias in node.names)
                else:
                    found.add(target[0])
            elif node.module and node.module.split(".")[0] == "rapid_cosim":
                rest = node.module.split(".")[1:]
                found.update([rest[0]] if rest else [a.name if (PACKAGE / a.name).is_dir() else FACE for a in node.names])
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
        if name == own or name in LEAVES:
            continue
        if name == FACE:  # the face imports every room: importing it is importing upwards
            bad.append("the package's face (rapid_cosim/__init__.py)")
            continue
        if LAYERS[name] >= LAYERS[own]:
            bad.append(f"{name} (layer {LAYERS[name]})")
    assert not bad, f"{'/'.join(parts)} (layer {LAYERS[own]}) imports against the flow: {', '.join(bad)}"


def test_leaves_import_nothing_from_the_package():
    for leaf in LEAVES:
        path = PACKAGE / f"{leaf}.py"
        assert not _imported(path, (leaf,)), leaf


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
                      "def f():\n    from ...api import calibrate\n    from rapid_cosim import fleet\n")
    assert _imported(module, ("simulator", "sub", "m")) == {"report", "simulator", "cli", "api", "fleet"}
    face = tmp_path / "f.py"
    face.write_text("from .. import __version__\n")
    assert _imported(face, ("archive", "f")) == {FACE}  # the face, which imports every room


def _module_graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports (lazy ones too). Imports under ``if
    TYPE_CHECKING:`` are annotations, not imports, and a module's import of its own
    package's ``__init__`` (which imports it) is Python's way of reaching a sibling."""
    names = {}
    for path, parts in _modules():
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = (path, parts)
    graph = {}
    for name, (path, parts) in names.items():
        package = list(parts[:-1])
        tree = ast.parse(path.read_text())
        skip = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
                for child in node.body for n in ast.walk(child)}
        out = set()
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package[: len(package) - (node.level - 1)]
                    target = base + (node.module.split(".") if node.module else [])
                elif (node.module or "").split(".")[0] == "rapid_cosim":
                    target = node.module.split(".")[1:]
                else:
                    continue
                for alias in node.names:
                    sub = ".".join(target + [alias.name])
                    out.add(sub if sub in names else ".".join(target))
            elif isinstance(node, ast.Import):
                out.update(".".join(a.name.split(".")[1:]) for a in node.names if a.name.startswith("rapid_cosim."))
        graph[name] = {t for t in out if t in names and t != name and not name.startswith(t + ".") and t}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in list(graph):
        if v not in index:
            visit(v)
    return found


def test_no_module_imports_itself_round_a_circle():
    assert not _cycles(_module_graph())


def test_the_circle_check_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert not _cycles({"a": {"b"}, "b": set()})


def test_only_the_face_errors_the_version_and_progress_sit_at_the_root():
    loose = {p.stem for p in PACKAGE.glob("*.py")} - ROOT_MODULES
    assert not loose, f"modules at the package root that belong in a room: {sorted(loose)}"


def test_the_version_is_the_projects():
    import tomllib

    from rapid_cosim.version import __version__

    project = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["project"]
    assert __version__ == project["version"]


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


# -- issue 43's rules: results typed until written, outcomes as data, no repository paths,
# -- modules short or saying why

RESULT_NAMES = ("Result", "Verdict", "Judgement", "Recommendation", "Identification", "Calibration", "Diagnosis",
                "Fit", "Playback", "Delivery", "Report", "Fidelity", "Explanation", "Advice", "AdvisedTest")
# Untyped fields still on a result, each with why it stays (the rule keeps new ones out): each
# is a file's payload (diagnosis.json, diagnosis.h5, identification.json, structures.json),
# built for it and read back only from the file; test_untyped_fields_are_not_read_by_key holds
# the package to not deciding by their keys.
UNTYPED_LEFT = {
    # the diagnosis: its verdict, adequacy and ranking are typed; the evidence below is written into
    # diagnosis.json as it is built, and only the report reads it back (from the JSON, not these fields)
    "DiagnosisVerdict.held_out": "the held-out check's figures (Verdict.held_out), written as they are",
    "AdequacyJudgement.unexplained": "where the remainder lies (misfit_locations), written as it is",
    "AdequacyJudgement.materiality": "each named effect's gap and size shares, written as they are",
    "SearchReport.profiles": "the named effects' profile likelihoods, written as they are",
    "SearchReport.variants": "the effect's variants tried, written as they are",
    "Diagnosis.features": "the recordings' features (Features.to_json), written as they are",
    "Diagnosis.gap_before": "each test's gap figures, written as they are",
    "Diagnosis.gap_after": "each test's gap figures, written as they are",
    "Diagnosis.noise": "each recorder's noise model with its uncertainty, written as it is",
    "Diagnosis.residuals": "per test, the residual arrays by name, as diagnosis.h5 holds them for the figures",
    "Diagnosis.timing": "the stamps' jitter and the variance it could add (jitter_share), written as it is",
    "Explanation.noise": "each recorder's noise model with its uncertainty, as diagnosis.json holds it",
    "Identification.recordings": "Recording.summary(), a JSON summary the report and the story print",
    "Verdict.held_out": "the held-out check's figures, written into diagnosis.json as they are",
    "StructureVerdict.effects": "the effect catalogue's diagnosis on the winner, as its JSON",
}


def _untyped(annotation: str) -> bool:
    """A field holding a dict whose values are not typed: ``dict``, ``dict | None``,
    ``dict[str, dict]`` (read back by string keys). A ``dict[str, float]`` of parameter
    values or a ``dict[str, TestJudgement]`` is typed."""
    a = annotation.replace(" ", "")
    return a in ("dict", "dict|None", "Mapping", "Optional[dict]") or a.endswith(",dict]") or ",dict[" in a


def _result_fields():
    for path, parts in _modules():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if not isinstance(node, ast.ClassDef) or not node.name.endswith(RESULT_NAMES):
                continue
            if not any("dataclass" in ast.unparse(d) for d in node.decorator_list):
                continue
            for st in node.body:
                if isinstance(st, ast.AnnAssign) and isinstance(st.target, ast.Name):
                    yield "/".join(parts), node.name, st.target.id, ast.unparse(st.annotation)


def test_result_dataclasses_have_no_untyped_dict_fields():
    found = [(where, f"{cls}.{name}: {ann}") for where, cls, name, ann in _result_fields()
             if _untyped(ann) and cls not in UNTYPED_LEFT and f"{cls}.{name}" not in UNTYPED_LEFT]
    assert not found, "untyped dict fields on results (a dataclass, or a reason in UNTYPED_LEFT): " + str(found)
    assert _untyped("dict") and _untyped("dict[str, dict]") and _untyped("dict | None")
    assert not _untyped("dict[str, float]") and not _untyped("dict[str, TestJudgement]")
    left = {k for k in UNTYPED_LEFT if "." in k}
    still = {f"{cls}.{name}" for _, cls, name, ann in _result_fields() if _untyped(ann)}
    assert left <= still, f"UNTYPED_LEFT names fields that are typed now (take them out): {left - still}"


OUTCOME_WORDS = ("unexplained", "ambiguous", "ties with", "unfinished", "fails", "passed", "identified", "named")
SENTENCES = ("reason", "message", "explanation", "words", "said", "verdict", "status", "text")


def _sentence(node: ast.AST) -> bool:
    """``x.reason`` or ``x["reason"]`` (a field that holds words)."""
    if isinstance(node, ast.Attribute):
        return node.attr in SENTENCES
    return isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and node.slice.value in SENTENCES


def _word(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and isinstance(node.value, str) and any(w in node.value for w in OUTCOME_WORDS)


def _outcome_searches(tree: ast.AST) -> list[str]:
    """``"word" in x.reason`` (or ``x["reason"]``; ``.startswith``/``.endswith``/``.find``/
    ``.count`` on such a field; ``re.search``/``match``/``fullmatch``/``findall`` over it)
    where the word names an outcome: an outcome tested by its sentence."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare) and any(isinstance(op, (ast.In, ast.NotIn)) for op in node.ops):
            if _word(node.left) and _sentence(node.comparators[0]):
                found.append(ast.unparse(node))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            f = node.func
            if f.attr in ("startswith", "endswith", "find", "count") and _sentence(f.value) and node.args \
                    and _word(node.args[0]):
                found.append(ast.unparse(node))
            elif isinstance(f.value, ast.Name) and f.value.id == "re" and f.attr in ("search", "match", "fullmatch",
                                                                                     "findall") \
                    and len(node.args) >= 2 and _word(node.args[0]) and _sentence(node.args[1]):
                found.append(ast.unparse(node))
    return found


def test_no_outcome_is_found_by_searching_a_sentence():
    found = [f"{'/'.join(parts)}: {s}" for path, parts in _modules() for s in _outcome_searches(ast.parse(path.read_text()))]
    assert not found, found
    caught = _outcome_searches(ast.parse('a = "unexplained" in r.explanation\nb = ident.reason.startswith("ties with")\n'
                                         'c = "x" in r.reason\nd = "unfinished" in fit.message\n'
                                         'e = re.search("ambiguous", d.verdict)\nf = "fails" in row["reason"]\n'))
    assert caught == ["'unexplained' in r.explanation", "ident.reason.startswith('ties with')",
                      "'unfinished' in fit.message", "re.search('ambiguous', d.verdict)", "'fails' in row['reason']"]


def test_the_package_does_not_reach_into_the_repository():
    """Installed from a wheel, the package has no experiments/, docs/ or benchmarks/
    beside it: no path climbs out of rapid_cosim (``parents[n]`` past the package, a
    ``.parent.parent`` chain from ``__file__``)."""
    bad = []
    for path, parts in _modules():
        depth = len(parts)  # rapid_cosim/a/b.py: parents[1] is rapid_cosim, parents[2] the repository
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Attribute) \
                    and node.value.attr == "parents" and isinstance(node.slice, ast.Constant) \
                    and "__file__" in ast.unparse(node.value) and node.slice.value >= depth:
                bad.append(f"{'/'.join(parts)}: {ast.unparse(node)}")
            if isinstance(node, ast.Attribute) and node.attr == "parent" and "__file__" in ast.unparse(node) \
                    and ast.unparse(node).count(".parent") > depth:
                bad.append(f"{'/'.join(parts)}: {ast.unparse(node)}")
    assert not bad, bad


LONG = 450
LONG_REASON = "Over 450 lines:"


def test_a_long_module_says_why():
    """A module over 450 lines says why in its docstring (``Over 450 lines: ...``)."""
    long = []
    for path, parts in _modules():
        text = path.read_text()
        if text.count("\n") > LONG:
            doc = ast.get_docstring(ast.parse(text)) or ""
            if LONG_REASON not in doc or len(doc.split(LONG_REASON, 1)[1].strip()) < 20:
                long.append(f"{'/'.join(parts)} ({text.count(chr(10))} lines)")
    assert not long, f"modules over {LONG} lines without '{LONG_REASON} <why>' in their docstring: {long}"


# The loose settings that ModelSource and EngineSpec stand for, and the rooms that may still
# take them one by one: the compiler (which ModelSource calls), the engine itself, and the
# CLI's parser (which reads them off the command line).
LOOSE = {"package": "source", "fmu_dir": "source", "compiler": "source", "n_jobs": "engine", "backend": "engine",
         "joblib_backend": "engine", "scheduler": "engine", "workers": "engine"}
LOOSE_ALLOWED = {("compiler",), ("fitting", "engine"), ("cli", "parser")}
# a parameter of the same name that means something else, each with its reason
LOOSE_ELSEWHERE = {
    ("diagnose/catalogue", "write_bench", "package"): "the package folder a bench is written into, not a source",
    ("fleet/result", "<field>", "workers"): "how many workers the fleet ran on: a figure of the result, not a setting",
}


def _loose_parameters(tree: ast.AST, where: str) -> list[str]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            a = node.args
            for arg in [*a.posonlyargs, *a.args, *a.kwonlyargs]:
                if arg.arg in LOOSE and (where, node.name, arg.arg) not in LOOSE_ELSEWHERE:
                    found.append(f"{where}: {node.name}({arg.arg}) -> {LOOSE[arg.arg]}")
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.target.id in LOOSE \
                and (where, "<field>", node.target.id) not in LOOSE_ELSEWHERE:
            found.append(f"{where}: field {node.target.id} -> {LOOSE[node.target.id]}")
    return found


def test_one_model_source_and_one_engine_are_passed_down():
    """Above the compiler and the engine, no function takes (and no dataclass holds) the
    package, the FMU folder, the compiler, the workers, the backend or the scheduler one by
    one: they travel as one ``ModelSource`` and one ``EngineSpec`` (issue 43)."""
    found = []
    for path, parts in _modules():
        if any(parts[:len(p)] == p for p in LOOSE_ALLOWED):
            continue
        found += _loose_parameters(ast.parse(path.read_text()), "/".join(parts))
    assert not found, found
    caught = _loose_parameters(ast.parse("def f(x, *, fmu_dir=None): ...\nclass O:\n    n_jobs: int = 1\n"
                                         "def write_bench(package): ...\n"), "diagnose/catalogue")
    assert caught == ["diagnose/catalogue: f(fmu_dir) -> source", "diagnose/catalogue: field n_jobs -> engine"]


KIND_WORDS = {"none", "ambiguous", "unexplained", "running", "finished", "interrupted", "unfinished"}
KIND_NAMES = {"NONE", "AMBIGUOUS", "UNEXPLAINED"}  # the words as constants: a verdict is built of them, not tested
KIND_FIELDS = {"effect", "structure", "status", "structure_verdict"}


def _kind_field(node: ast.AST) -> bool:
    """``x.effect`` or ``x["effect"]`` (and structure, status): a field holding a verdict's or a
    run's word (a dask ``client.status`` is dask's own)."""
    if isinstance(node, ast.Attribute):
        return node.attr in KIND_FIELDS and not (isinstance(node.value, ast.Name) and node.value.id == "client")
    return isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and node.slice.value in KIND_FIELDS


def _kind_word(node: ast.AST) -> bool:
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return any(_kind_word(e) for e in node.elts)
    return (isinstance(node, ast.Constant) and node.value in KIND_WORDS) or (
        isinstance(node, ast.Name) and node.id in KIND_NAMES)


def _kinds_by_word(tree: ast.AST) -> list[str]:
    """``verdict.effect == AMBIGUOUS``, ``view.status != "finished"``: a kind told by its word
    rather than by its enum (``verdict.kind is VerdictKind.AMBIGUOUS``, ``RunStatus.FINISHED``)."""
    return [ast.unparse(node) for node in ast.walk(tree) if isinstance(node, ast.Compare)
            and any(_kind_field(a) and _kind_word(b) or _kind_word(a) and _kind_field(b)
                    for a, b in zip([node.left, *node.comparators], node.comparators))]


def test_verdicts_and_statuses_are_told_by_their_enums():
    """Issue 57: a verdict's kind (VerdictKind) and a run's status (RunStatus) are compared as
    enums; the words stay what JSON and archives hold."""
    found = [f"{'/'.join(parts)}: {s}" for path, parts in _modules() for s in _kinds_by_word(ast.parse(path.read_text()))]
    assert not found, found
    assert _kinds_by_word(ast.parse("v.effect == AMBIGUOUS")) and _kinds_by_word(ast.parse('s.status != "finished"'))
    assert _kinds_by_word(ast.parse('r["effect"] in (NONE, "x")'))
    assert not _kinds_by_word(ast.parse("v.kind is VerdictKind.AMBIGUOUS")) and not _kinds_by_word(
        ast.parse("r.label == BASE"))


USER_ROOMS = ("api", "experiment", "data", "identify", "fleet", "structures", "exchange", "check", "cli", "examples")
VALUE_ERRORS_LEFT = {  # (module, function) -> why its ValueError never reaches a user as it is
    ("data/pmu", "parse_timestamp"): "a parser's contract, like int(): each caller names the file and row (DataError)",
    ("experiment/toml_writer", "_toml_value"): "a writer's contract: check's every_problem catches it and writes the rest",
    ("data/measured", "sample_onto"): "arrays the package computes (a simulation's time base), not a user's input",
}


def _value_errors(tree: ast.AST) -> list[tuple[str, int]]:
    """(enclosing function, line) of each ``raise ValueError(...)``."""
    found = []

    def visit(node, function):
        for child in ast.iter_child_nodes(node):
            name = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else function
            if isinstance(child, ast.Raise) and child.exc is not None:
                exc = child.exc.func if isinstance(child.exc, ast.Call) else child.exc
                if isinstance(exc, ast.Name) and exc.id == "ValueError":
                    found.append((function, child.lineno))
            visit(child, name)

    visit(tree, "<module>")
    return found


def test_no_value_error_reaches_a_user_from_the_rooms_their_input_enters():
    """Issue 57: what a user's config, recording, record or call gets wrong is a
    RapidCosimError that names it (the CLI prints those; a ValueError was a traceback)."""
    found, used = [], set()
    for path, parts in _modules():
        if parts[0].removesuffix(".py") not in USER_ROOMS:
            continue
        module = "/".join(parts)
        for function, line in _value_errors(ast.parse(path.read_text())):
            if (module, function) in VALUE_ERRORS_LEFT:
                used.add((module, function))
            else:
                found.append(f"{module}:{line} ({function})")
    assert not found, found
    assert used == set(VALUE_ERRORS_LEFT), f"VALUE_ERRORS_LEFT names what raises no ValueError now: {set(VALUE_ERRORS_LEFT) - used}"
    assert _value_errors(ast.parse("def f():\n    raise ValueError('x')\n")) == [("f", 2)]


def _maps_fits(tree: ast.AST) -> list[str]:
    """``engine.make().map(...)`` and ``[np.array([k]) for k in ...]``: whole fits mapped by hand."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "map" \
                and isinstance(node.func.value, ast.Call) and isinstance(node.func.value.func, ast.Attribute) \
                and node.func.value.func.attr == "make":
            found.append(ast.unparse(node))
        elif isinstance(node, ast.ListComp) and ast.unparse(node.elt) == "np.array([k])":
            found.append(ast.unparse(node))
    return found


def test_whole_fits_are_mapped_by_one_helper():
    """Issue 57: the diagnosis's candidates and the standard structures are fitted whole on
    local workers through fitting.engine.map_fits, one payload shape (WholeFits)."""
    found = [f"{'/'.join(parts)}: {s}" for path, parts in _modules() if parts != ("fitting", "engine")
             for s in _maps_fits(ast.parse(path.read_text()))]
    assert not found, found
    assert _maps_fits(ast.parse("parts = e.make().map(f, p, [np.array([k]) for k in range(3)])")) == [
        "e.make().map(f, p, [np.array([k]) for k in range(3)])", "[np.array([k]) for k in range(3)]"]
    uses = {"/".join(parts) for path, parts in _modules() if "map_fits(" in path.read_text()}
    assert {"diagnose/context", "structures/calibrations"} <= uses


def test_reasons_are_clauses_joined_once():
    """Issue 57: a verdict's reason, a record's words, a time base's description are lists
    of clauses joined where they are made, not strings grown by ``+=``."""
    found = [f"{'/'.join(parts)}:{node.lineno}: {ast.unparse(node)}" for path, parts in _modules()
             for node in ast.walk(ast.parse(path.read_text()))
             if isinstance(node, ast.AugAssign) and isinstance(node.op, ast.Add) and isinstance(node.target, ast.Name)
             and node.target.id in ("reason", "words", "said", "verdict", "explanation")]
    assert not found, found


# The adequacy sequence's steps, called only by diagnose/judging (and where each is defined).
JUDGING_STEPS = {"adequacy": ("diagnose", "adequacy"), "replicates_for": ("diagnose", "null"),
                 "noise_floors": ("diagnose", "selection")}


def _judging_steps(tree: ast.AST) -> list[str]:
    """Calls of the adequacy sequence's steps (``adequacy(...)``, ``replicates_for(...)``,
    ``noise_floors(...)``), by name or as their module's attribute (not a method of the
    same name: the diagnosis's ``ctx.adequacy(fit)`` judges through its Judge)."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            by_module = isinstance(f, ast.Attribute) and ast.unparse(f.value) in ("adequacy", "null", "selection")
            name = f.id if isinstance(f, ast.Name) else f.attr if by_module else None
            if name in JUDGING_STEPS:
                found.append(f"{node.lineno}: {ast.unparse(node)[:60]}")
    return found


def test_the_adequacy_sequence_is_written_once():
    """Issue 57: noise fits, floors, the null's replicates and the adequacy judged are one
    sequence (diagnose.judging.Judge) that the diagnosis, the structures and the fleet's
    playback all take; written by hand it drifted (three copies)."""
    allowed = {("diagnose", "judging"), *JUDGING_STEPS.values()}
    found = [f"{'/'.join(parts)}:{s}" for path, parts in _modules() if parts not in allowed
             for s in _judging_steps(ast.parse(path.read_text()))]
    assert not found, found
    assert _judging_steps(ast.parse("a = adequacy(t, f, n, None, [])\nb = null.replicates_for(e, f)\n"
                                    "c = self.adequacy(fit)\n")) == [
        "1: adequacy(t, f, n, None, [])", "2: null.replicates_for(e, f)"]
    uses = {"/".join(parts) for path, parts in _modules() if "Judge.of(" in path.read_text()}
    assert {"diagnose/context", "structures/select", "fleet/playback"} <= uses


def test_the_judgement_takes_nothing_from_the_report():
    """Issue 57, item 6: whether a record reproduces a recording is decided in validation/
    (the curves compared, the metrics, the bands) and diagnose/ (the noise tests); report/
    only draws and writes. The fleet's playback once judged through report/'s curves."""
    judging = [("fleet", "playback"), ("fleet", "unit_job"), ("fleet", "runner")]
    for parts in judging:
        imported = _imported(PACKAGE.joinpath(*parts[:-1], parts[-1] + ".py"), parts)
        assert "report" not in imported, f"{'/'.join(parts)} judges through report/"
    validation = [parts for _, parts in _modules() if parts[0] == "validation"]
    assert ("validation", "curves") in validation


# Functions over LONG_FUNCTION lines, each with the reason it is read best whole.
LONG_FUNCTION = 80
LONG_FUNCTIONS = {
    "diagnose/catalogue.bench_source": "one Modelica class written top to bottom (header, components, connections, "
                                       "annotation); split, its text is read out of order",
    "estimators/lm.levenberg_marquardt": "one lockstep loop over every start whose state (points, damping, status, "
                                         "merges, iterations) each step updates together, with its recorder",
    "estimators/smc.smc": "the tempered SMC loop (next temperature, reweight, resample, move) as the algorithm reads; "
                          "its state is shared by every step",
    "simulator/reference._integrate": "FMI's calling sequence for one simulation (set up, initialise, the event and "
                                      "step loop, outputs), in fmpy's order, so that it is checked against it",
}


def test_long_functions_have_their_reasons():
    """Issue 57: no function over 80 lines without a stated reason (a module over 450 lines:
    test_a_long_module_says_why); a reason for one that is short now is taken out."""
    long_functions = {}
    for path, parts in _modules():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and \
                    node.end_lineno - node.lineno + 1 > LONG_FUNCTION:
                long_functions[f"{'/'.join(parts)}.{node.name}"] = node.end_lineno - node.lineno + 1
    assert set(long_functions) == set(LONG_FUNCTIONS), (
        f"over {LONG_FUNCTION} lines without a reason: {set(long_functions) - set(LONG_FUNCTIONS)}; "
        f"reasons for functions that are short now: {set(LONG_FUNCTIONS) - set(long_functions)}")


def _key_reads(tree: ast.AST, fields: set[str]) -> list[str]:
    """``x.field["key"]`` and ``x.field.get(...)`` outside to_json/from_json: a decision
    reading an untyped field by its keys."""
    found = []
    for fn in ast.walk(tree):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)) or fn.name in ("to_json", "from_json"):
            continue
        for n in ast.walk(fn):
            if isinstance(n, ast.Subscript) and isinstance(n.value, ast.Attribute) and n.value.attr in fields \
                    and isinstance(n.slice, ast.Constant) and isinstance(n.slice.value, str):
                found.append(f"{fn.name}: {ast.unparse(n)}")
            elif isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute) and n.func.attr == "get" \
                    and isinstance(n.func.value, ast.Attribute) and n.func.value.attr in fields:
                found.append(f"{fn.name}: {ast.unparse(n)}")
    return found


def test_untyped_fields_are_not_read_by_key():
    """Issue 57, item 2: what UNTYPED_LEFT keeps as a dict is written into its file and
    read back from the file; nothing in the package decides by reading its keys."""
    fields = {k.split(".")[1] for k in UNTYPED_LEFT if "." in k}
    found = [f"{'/'.join(parts)}: {s}" for path, parts in _modules() for s in _key_reads(ast.parse(path.read_text()), fields)]
    assert not found, found
    assert _key_reads(ast.parse("def f(v):\n    return v.held_out['tests'], v.noise.get('a')\n"
                                "def to_json(self):\n    return self.noise['a']\n"), {"held_out", "noise"}) == [
        "f: v.held_out['tests']", "f: v.noise.get('a')"]


def _engine_defaults(tree: ast.AST) -> list[str]:
    """``name=default`` of every ``EngineSpec``-annotated argument whose default is not ``EngineSpec()``."""
    found = []
    for fn in ast.walk(tree):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        args = fn.args.args + fn.args.kwonlyargs
        defaults = [None] * (len(fn.args.args) - len(fn.args.defaults)) + fn.args.defaults + fn.args.kw_defaults
        for arg, default in zip(args, defaults):
            if arg.annotation is not None and ast.unparse(arg.annotation) == "EngineSpec" and default is not None \
                    and ast.unparse(default) != "EngineSpec()":
                found.append(f"{fn.name}: {arg.arg}={ast.unparse(default)}")
    return found


def test_one_default_engine():
    """Issue 57, item 4: every function of the package that takes an ``engine`` defaults to
    ``EngineSpec()`` (the staged campaign once took two workers and the fleet a dask pair)."""
    found = [f"{'/'.join(parts)}.{s}" for path, parts in _modules() for s in _engine_defaults(ast.parse(path.read_text()))]
    assert not found, found
    assert _engine_defaults(ast.parse("def f(a, engine: EngineSpec = EngineSpec(n_jobs=2), *, e2: EngineSpec = EngineSpec()):"
                                      "\n    pass\n")) == ["f: engine=EngineSpec(n_jobs=2)"]
