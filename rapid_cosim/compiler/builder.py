"""Which FMUs to build, with which compiler, and whether they need building at all.

Each FMU gets a manifest beside it (``<model>.manifest.json``): the hash of the Modelica
sources the model is built from (the classes it uses, see ``model_sha256``), the compiler
and an identity of its tool chain. An FMU is rebuilt only when one of those changes, so
``make fmus`` is cheap to call before every experiment, and adding a model to the
package rebuilds nothing else.

Built FMUs are also kept in a cache shared by every FMU folder of the user
(``<cache_dir>/fmus``), under the hash of model, sources and tool chain: a diagnosis
that compiles its candidate benches into a fresh work folder, or a study that runs many
of them, compiles each distinct model once. A lock per model and FMU folder makes a
second process wait while the first builds, then take its FMU.

No default depends on the current folder: the package is the iGrGen shipped inside
rapid_cosim (:func:`default_package`), the FMUs go into the user's cache, a folder per
version of rapid-cosim (:func:`default_fmu_dir`); ``$RAPID_COSIM_PACKAGE`` and ``$RAPID_COSIM_FMUS`` name others
(the repository's Makefile sets the second to its ``fmus/``, a developer's view).
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import os
import shutil
import subprocess
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from pathlib import Path

from ..version import __version__
from ..errors import BuildError
from .embedded import c_compiler, cache_dir
from .modelica_source import PackageSource, class_index, load_package, model_sha256
from .openmodelica import find_omc

COMPILERS = ("auto", "openmodelica", "embedded")
LOCK_TIMEOUT_S = 600.0  # a build waited for longer than this is an error (a build takes seconds)


def default_package() -> Path:
    """``$RAPID_COSIM_PACKAGE``, else the iGrGen package shipped inside rapid_cosim."""
    configured = os.environ.get("RAPID_COSIM_PACKAGE")
    if configured:
        return Path(configured)
    from importlib.resources import files

    return Path(str(files("rapid_cosim") / "modelica" / "iGrGen"))


def default_fmu_dir() -> Path:
    """``$RAPID_COSIM_FMUS``, else a folder of the user's cache for this version of
    rapid-cosim: two installed versions ship different sources, and one must not replace
    the other's FMU under a run."""
    from ..version import __version__

    configured = os.environ.get("RAPID_COSIM_FMUS")
    return Path(configured) if configured else cache_dir() / "fmu" / __version__


def resolve_models(package: str | Path | None, fmu_dir: str | Path | None) -> tuple[Path, Path]:
    """``package`` and ``fmu_dir`` as paths, the defaults where None."""
    return (Path(package) if package is not None else default_package(),
            Path(fmu_dir) if fmu_dir is not None else default_fmu_dir())


@dataclass(frozen=True)
class Manifest:
    model: str
    fmu: str
    compiler: str
    compiler_id: str
    source_hash: str
    fmu_sha256: str
    fmi_version: str
    fmi_type: str
    tools: dict
    built: str
    build_seconds: float


@dataclass(frozen=True)
class BuildOutcome:
    model: str
    fmu: Path
    rebuilt: bool
    manifest: Manifest


def check_compiler(compiler: str) -> str:
    if compiler not in COMPILERS:
        raise BuildError(f"unknown compiler {compiler!r}; choose one of {', '.join(COMPILERS)}")
    return compiler


def resolve_compiler(compiler: str) -> str:
    if check_compiler(compiler) == "auto":
        return "openmodelica" if find_omc() else "embedded"
    return compiler


def package_digest(package: str | Path | None = None) -> str:
    """A digest of every source file of a Modelica package (names relative to it and
    contents): what results made from its models depend on, wherever it lies."""
    root = resolve_models(package, None)[0]
    h = hashlib.blake2b(digest_size=16)
    files = [root] if root.is_file() else sorted(p for p in root.rglob("*") if p.suffix == ".mo"
                                                  or p.name == "package.order")
    for f in files:
        h.update(str(f.relative_to(root) if root.is_dir() else f.name).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def fmu_path(model: str, fmu_dir: str | Path | None = None) -> Path:
    return (Path(fmu_dir) if fmu_dir is not None else default_fmu_dir()) / f"{model}.fmu"


def manifest_path(fmu: Path) -> Path:
    return fmu.with_name(fmu.name[: -len(".fmu")] + ".manifest.json")


def test_benches(source: PackageSource) -> list[str]:
    """The models of ``<package>.TestBenches``: what ``make fmus`` builds by default."""
    prefix = f"{source.name}.TestBenches."
    return [n for n, e in class_index(source).items() if e.kind == "model" and n.startswith(prefix)]


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "absent"


def _compiler_version() -> str:
    cc = c_compiler()
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True).stdout
        return out.splitlines()[0] if out else cc
    except FileNotFoundError:
        return f"{cc} (not found)"


def _embedded_identity() -> tuple[str, dict]:
    """The embedded compiler's own sources are part of its identity: editing the
    translator must rebuild the FMUs it made."""
    here = Path(__file__).parent
    h = hashlib.sha256()
    for f in sorted([here / "modelica_source.py", *(here / "embedded").glob("*.py"), *(here / "embedded").glob("*.c")]):
        h.update(f.read_bytes())
    tools = {"rapid-cosim": __version__, "pymoca": _version("pymoca"), "casadi": _version("casadi"),
             "fmpy": _version("fmpy"), "compiler": _compiler_version()}
    h.update(json.dumps(tools, sort_keys=True).encode())
    return h.hexdigest(), tools


def _openmodelica_identity() -> tuple[str, dict]:
    omc = find_omc() or "omc"
    try:
        version = subprocess.run([omc, "--version"], capture_output=True, text=True).stdout.strip()
    except FileNotFoundError:
        version = "absent"
    tools = {"rapid-cosim": __version__, "omc": version, "OMPython": _version("OMPython")}
    return hashlib.sha256(json.dumps(tools, sort_keys=True).encode()).hexdigest(), tools


def read_manifest(fmu: Path) -> Manifest | None:
    path = manifest_path(fmu)
    if not path.exists():
        return None
    try:
        return Manifest(**json.loads(path.read_text()))
    except (TypeError, ValueError):
        return None


def build_models(models: list[str] | None = None, *, package: str | Path | None = None,
                 fmu_dir: str | Path | None = None, compiler: str = "auto", force: bool = False,
                 log=print) -> list[BuildOutcome]:
    """Build (or confirm up to date) the FMUs of ``models``; default: every test bench."""
    package, fmu_dir = resolve_models(package, fmu_dir)
    if not package.exists():
        raise BuildError(f"no Modelica package at {package} (--package, source=ModelSource(package=...) of the API, $RAPID_COSIM_PACKAGE)")
    source, known = _parsed(package)
    chosen = resolve_compiler(compiler)
    models = models or test_benches(source)
    unknown = [m for m in models if m not in known]
    if unknown:
        import difflib

        close = difflib.get_close_matches(unknown[0], [n for n, e in known.items() if e.kind == "model"], n=1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise BuildError(f"unknown model(s) {', '.join(unknown)}{hint}; test benches: "
                         f"{', '.join(test_benches(source))}")
    compiler_id, tools = _embedded_identity() if chosen == "embedded" else _openmodelica_identity()
    outcomes, omc_builder, tree = [], None, None
    try:
        for model in models:
            source_hash = model_sha256(source, model, known)
            fmu = fmu_path(model, fmu_dir)
            with _build_lock(fmu):  # another process building it: wait, then find it fresh
                old = read_manifest(fmu)
                if not force and _fresh(old, fmu, source_hash, chosen, compiler_id):
                    outcomes.append(BuildOutcome(model, fmu, False, old))
                    log(f"  {model}: up to date ({chosen})")
                    continue
                cached = None if force else _from_cache(model, fmu, source_hash, chosen, compiler_id)
                if cached is not None:
                    outcomes.append(BuildOutcome(model, fmu, False, cached))
                    log(f"  {model}: up to date ({chosen}, from the cache)")
                    continue
                t0 = time.perf_counter()
                if chosen == "embedded":
                    from .embedded.fmu_writer import write_fmu
                    from .embedded.frontend import parse, translate

                    tree = tree if tree is not None else parse(source)
                    generation_tool = (f"rapid-cosim {__version__} embedded (pymoca {tools['pymoca']}, "
                                       f"casadi {tools['casadi']})")
                    write_fmu(translate(source, model, tree), fmu, generation_tool=generation_tool,
                              source_hash=source_hash)
                else:
                    from .openmodelica import OpenModelicaBuilder

                    omc_builder = omc_builder or OpenModelicaBuilder(source.top_file)
                    omc_builder.build(model, fmu)
                seconds = time.perf_counter() - t0
                manifest = Manifest(
                    model=model, fmu=fmu.name, compiler=chosen, compiler_id=compiler_id, source_hash=source_hash,
                    fmu_sha256=_sha256(fmu), fmi_version="2.0", fmi_type="ModelExchange", tools=tools,
                    built=datetime.now(timezone.utc).isoformat(timespec="seconds"), build_seconds=round(seconds, 3))
                manifest_path(fmu).write_text(json.dumps(asdict(manifest), indent=2) + "\n")
                _to_cache(fmu, manifest)
                outcomes.append(BuildOutcome(model, fmu, True, manifest))
                log(f"  {model}: built ({chosen}, {seconds:.2f} s)")
    finally:
        if omc_builder is not None:
            omc_builder.close()
    return outcomes


@contextmanager
def _build_lock(fmu: Path):
    """Held while ``fmu`` is checked and built: one process at a time, across processes
    (a file in ``.locks`` beside it)."""
    from filelock import FileLock, Timeout

    locks = fmu.parent / ".locks"
    locks.mkdir(parents=True, exist_ok=True)
    lock = FileLock(locks / f"{fmu.name}.lock")
    try:
        lock.acquire(timeout=LOCK_TIMEOUT_S)
    except Timeout:
        raise BuildError(f"{fmu}: another process has been building it for {LOCK_TIMEOUT_S:.0f} s "
                         f"(lock {lock.lock_file}); remove the lock file if no build is running") from None
    try:
        yield
    finally:
        lock.release()


def _cache_path(model: str, source_hash: str, compiler: str, compiler_id: str) -> Path:
    key = hashlib.sha256(f"{model}|{source_hash}|{compiler}|{compiler_id}".encode()).hexdigest()[:24]
    return cache_dir() / "fmus" / f"{model}-{key}.fmu"


def _from_cache(model: str, fmu: Path, source_hash: str, compiler: str, compiler_id: str) -> Manifest | None:
    """Copy a cached build of the same sources and tool chain into place, with its manifest."""
    cached = _cache_path(model, source_hash, compiler, compiler_id)
    manifest = read_manifest(cached)
    if manifest is None or not cached.exists() or _sha256(cached) != manifest.fmu_sha256:
        return None
    fmu.parent.mkdir(parents=True, exist_ok=True)
    part = fmu.with_name(f"{fmu.name}.{os.getpid()}.part")
    shutil.copyfile(cached, part)
    os.replace(part, fmu)
    manifest_path(fmu).write_text(json.dumps(asdict(manifest), indent=2) + "\n")
    return manifest


def _to_cache(fmu: Path, manifest: Manifest) -> None:
    cached = _cache_path(manifest.model, manifest.source_hash, manifest.compiler, manifest.compiler_id)
    try:
        cached.parent.mkdir(parents=True, exist_ok=True)
        part = cached.with_name(f"{cached.name}.{os.getpid()}.part")
        shutil.copyfile(fmu, part)
        manifest_path(cached).write_text(json.dumps(asdict(manifest), indent=2) + "\n")
        os.replace(part, cached)  # the FMU last: a cached FMU always has its manifest
    except OSError:  # a cache that cannot be written only costs later rebuilds
        pass


def _fresh(old: Manifest | None, fmu: Path, source_hash: str, compiler: str, compiler_id: str) -> bool:
    if old is None or not fmu.exists():
        return False
    same = (old.source_hash, old.compiler, old.compiler_id) == (source_hash, compiler, compiler_id)
    return same and old.fmu_sha256 == _sha256(fmu)


def _stats(paths) -> tuple:
    out = []
    for p in paths:
        try:
            st = os.stat(p)
            out.append((str(p), st.st_size, st.st_mtime_ns))
        except OSError:
            out.append((str(p), None, None))
    return tuple(out)


def _package_signature(package: Path) -> tuple:
    """Every source file of the package by path, size and modification time: a stat each,
    far cheaper than parsing, and it changes whenever a source does."""
    if not package.is_dir():
        return _stats([package])
    return _stats(sorted(os.path.join(root, f) for root, _, names in os.walk(package) for f in names
                         if f.endswith(".mo") or f == "package.order"))


def _signature(package: Path, fmu: Path) -> tuple:
    """What an up-to-date FMU depends on: the package's sources and the FMU itself."""
    return _package_signature(package) + _stats([fmu, manifest_path(fmu)])


# Per process: each package parsed once while its sources stay as they are (a diagnosis
# asks for a dozen benches of one package).
_PARSED: dict[str, tuple] = {}


def _parsed(package: Path):
    """(the package's source, its class index), parsed again only when a source changed."""
    key = str(package.resolve())
    signature = _package_signature(package)
    known = _PARSED.get(key)
    if known is None or known[0] != signature:
        source = load_package(package)
        known = _PARSED[key] = (signature, source, class_index(source))
    return known[1], known[2]


# Per process: the answers of ensure_fmu while nothing they depend on has changed, so that
# a notebook's repeated simulate() does not parse the package on every call.
_CURRENT: dict[tuple, tuple[tuple, Path]] = {}


def ensure_fmu(model: str, *, package: str | Path | None = None, fmu_dir: str | Path | None = None,
               compiler: str = "auto") -> Path:
    """Path of an up-to-date FMU for ``model`` (a class name or a path to an .fmu)."""
    if model.endswith(".fmu"):
        path = Path(model)
        if not path.exists():
            raise BuildError(f"FMU {path} does not exist")
        return path
    package, fmu_dir = resolve_models(package, fmu_dir)
    if not package.exists():
        fmu = fmu_path(model, fmu_dir)
        if fmu.exists():
            return fmu
        raise BuildError(f"no FMU {fmu} and no Modelica package at {package} to build it from: name the package "
                         "(--package, or ModelSource(package=...) of the API) or a folder holding the FMU (--fmus, "
                         "ModelSource(fmu_dir=...))")
    key = (model, str(package.resolve()), str(fmu_dir.resolve()), compiler)
    signature = _signature(Path(package), fmu_path(model, fmu_dir))
    known = _CURRENT.get(key)
    if known is not None and known[0] == signature:
        return known[1]
    fmu = build_models([model], package=package, fmu_dir=fmu_dir, compiler=compiler, log=lambda *_: None)[0].fmu
    _CURRENT[key] = (_signature(Path(package), fmu), fmu)
    return fmu
