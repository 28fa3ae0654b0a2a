"""A Modelica package directory read as one text, with the way back to files and lines.

pymoca parses one string and reports errors by line in that string; OMC wants the
package on disk. Assembling the package-directory layout (``package.mo``,
``package.order``, one file per class) into a single text with a line map serves both:
errors point at the user's file and line, and the hash of the files decides rebuilds.

The lexical index (class extents and the names each class refers to) lets the embedded
compiler reject unsupported constructs with a location, which pymoca's AST lacks, and
only where they matter: in classes the compiled model actually uses.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ModelicaError, UnsupportedConstruct

_WITHIN = re.compile(r"^\s*within\b[^;]*;", re.MULTILINE)
_CLASS_KEYWORDS = {"model", "block", "connector", "package", "record", "function", "type", "class"}
_BLOCK_ENDS = {"if", "for", "when", "while"}

# What the embedded path cannot translate, and how to name it in an error.
_UNSUPPORTED_KEYWORDS = {
    "when": "when-equation",
    "elsewhen": "when-equation",
    "redeclare": "redeclare",
    "algorithm": "algorithm section",
    "enumeration": "enumeration",
}
_UNSUPPORTED_CALLS = {
    "pre": "pre()",
    "edge": "edge()",
    "change": "change()",
    "reinit": "reinit()",
    "sample": "sample()",
    "initial": "initial()",
    "terminal": "terminal()",
    "delay": "delay() (on a known input use iGrGen.Effects.TransportDelay, exact; inside a loop iGrGen.Effects.PadeDelay)",
    "spatialDistribution": "spatialDistribution()",
    "cardinality": "cardinality()",
}


@dataclass(frozen=True)
class _Segment:
    file: Path
    first_line: int  # line in ``file`` of the segment's first line
    start: int  # line in the assembled text of the segment's first line
    n_lines: int


@dataclass(frozen=True)
class Token:
    text: str
    line: int  # in the assembled text


@dataclass
class ClassExtent:
    name: str  # full name, e.g. iGrGen.Governors.TGTypeI
    kind: str
    first_line: int
    last_line: int
    references: set[str] = field(default_factory=set)  # names as written, resolved later


@dataclass
class PackageSource:
    """The assembled text of one package directory."""

    root: Path
    name: str
    text: str
    files: tuple[Path, ...]
    _segments: tuple[_Segment, ...]

    def locate(self, line: int) -> tuple[str, int]:
        """File and line in that file for a line of the assembled text."""
        for seg in self._segments:
            if seg.start <= line < seg.start + seg.n_lines:
                return str(seg.file), seg.first_line + (line - seg.start)
        last = self._segments[-1]
        return str(last.file), last.first_line + last.n_lines - 1

    @property
    def top_file(self) -> Path:
        """What a Modelica tool loads: the top ``package.mo``, or the single ``.mo`` file."""
        return self.files[0]

    def sha256(self) -> str:
        h = hashlib.sha256()
        for f in self.files:
            h.update(str(f.relative_to(self.root.parent)).encode())
            h.update(f.read_bytes())
        return h.hexdigest()

    def error(self, message: str, line: int, cls=ModelicaError) -> ModelicaError:
        file, file_line = self.locate(line)
        return cls(message, file=file, line=file_line)


def load_package(path: str | Path) -> PackageSource:
    """Read a package directory (or a single ``.mo`` file) into one text."""
    path = Path(path).resolve()
    if path.is_file():
        root, pkg_file = path.parent, path
    else:
        root, pkg_file = path, path / "package.mo"
    if not pkg_file.exists():
        raise ModelicaError(f"no package.mo in {path}")
    chunks: list[tuple[Path, int, str]] = []
    files: list[Path] = []
    if path.is_file():
        chunks.append((pkg_file, 1, _strip_within(pkg_file.read_text())))
        files.append(pkg_file)
    else:
        _assemble(root, chunks, files)
    text, segments, line = [], [], 1
    for file, first_line, chunk in chunks:
        if not chunk.endswith("\n"):
            chunk += "\n"
        n = chunk.count("\n")
        segments.append(_Segment(file, first_line, line, n))
        text.append(chunk)
        line += n
    name = root.name if path.is_dir() else pkg_file.stem
    return PackageSource(root, name, "".join(text), tuple(files), tuple(segments))


def _strip_within(text: str) -> str:
    # Blank the clause out rather than delete it, so that line numbers stay true.
    return _WITHIN.sub(lambda m: " " * len(m.group(0)), text, count=1)


def _assemble(directory: Path, chunks: list, files: list) -> None:
    pkg_file = directory / "package.mo"
    text = _strip_within(pkg_file.read_text())
    files.append(pkg_file)
    tail = _last_end(text, directory.name)
    if tail is None:
        raise ModelicaError(f"'end {directory.name};' not found", file=str(pkg_file))
    tail = _own_annotation(text, tail)
    head = text[:tail]
    chunks.append((pkg_file, 1, head))
    for child in _children(directory):
        sub = directory / child
        if (sub / "package.mo").exists():
            _assemble(sub, chunks, files)
        else:
            f = directory / f"{child}.mo"
            files.append(f)
            chunks.append((f, 1, _strip_within(f.read_text())))
    chunks.append((pkg_file, head.count("\n") + 1, text[tail:]))


def _children(directory: Path) -> list[str]:
    order = directory / "package.order"
    present = {p.stem for p in directory.glob("*.mo") if p.name != "package.mo"}
    present |= {p.name for p in directory.iterdir() if (p / "package.mo").exists()}
    if order.exists():
        listed = [line.strip() for line in order.read_text().splitlines() if line.strip()]
        missing = [c for c in listed if c not in present]
        if missing:
            raise ModelicaError(f"package.order lists {missing}, which have no file", file=str(order))
        return listed + sorted(present - set(listed))
    return sorted(present)


def _own_annotation(text: str, end: int) -> int:
    """Where the package's own annotation starts, if it closes the package (the classes
    from files go before it: a class annotation is the last element of a class)."""
    masked = _mask_comments_and_strings(text[:end])
    found = list(re.finditer(r"\bannotation\s*\(", masked))
    if found and masked[found[-1].start():].count(";") == 1:
        return found[-1].start()
    return end


def _last_end(text: str, name: str) -> int | None:
    masked = _mask_comments_and_strings(text)
    matches = list(re.finditer(rf"\bend\s+{re.escape(name)}\s*;", masked))
    return matches[-1].start() if matches else None


def _mask_comments_and_strings(text: str) -> str:
    """Same length and line breaks, with comments and strings blanked."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*|'[^']*'|\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+|<=|>=|==|<>|:=|[^\sA-Za-z0-9_]")


def tokenize(text: str) -> list[Token]:
    masked = _mask_comments_and_strings(text)
    tokens, line, pos = [], 1, 0
    for m in _TOKEN.finditer(masked):
        line += masked.count("\n", pos, m.start())
        pos = m.start()
        tokens.append(Token(m.group(0), line))
    return tokens


def class_index(source: PackageSource) -> dict[str, ClassExtent]:
    """Full class name -> extent and the (unresolved) names its body mentions."""
    tokens = tokenize(source.text)
    index: dict[str, ClassExtent] = {}
    stack: list[ClassExtent] = []
    i = 0
    while i < len(tokens):
        t = tokens[i].text
        if t in _CLASS_KEYWORDS and i + 1 < len(tokens) and _is_ident(tokens[i + 1].text) \
                and not (i > 0 and tokens[i - 1].text == "end"):
            name = tokens[i + 1].text
            full = ".".join([c.name for c in stack[-1:]] + [name]) if stack else name
            ext = ClassExtent(full, t, tokens[i].line, tokens[i].line)
            index[full] = ext
            short = i + 2 < len(tokens) and tokens[i + 2].text == "="
            if short:
                j = i + 3
                while j < len(tokens) and tokens[j].text != ";":
                    _collect_reference(tokens, j, ext)
                    j += 1
                ext.last_line = tokens[min(j, len(tokens) - 1)].line
                i = j + 1
                continue
            stack.append(ext)
            i += 2
            continue
        if t == "end" and i + 1 < len(tokens):
            nxt = tokens[i + 1].text
            if nxt not in _BLOCK_ENDS and stack and nxt == stack[-1].name.rsplit(".", 1)[-1]:
                stack[-1].last_line = tokens[i + 1].line
                stack.pop()
                i += 2
                continue
        if stack:
            _collect_reference(tokens, i, stack[-1])
        i += 1
    return index


def _is_ident(text: str) -> bool:
    return bool(re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", text))


def _collect_reference(tokens: list[Token], i: int, ext: ClassExtent) -> None:
    """Record a dotted name starting at token i (only at its first segment)."""
    if not _is_ident(tokens[i].text) or (i > 0 and tokens[i - 1].text == "."):
        return
    parts, j = [tokens[i].text], i + 1
    while j + 1 < len(tokens) and tokens[j].text == "." and _is_ident(tokens[j + 1].text):
        parts.append(tokens[j + 1].text)
        j += 2
    ext.references.add(".".join(parts))


def resolve(name: str, scope: str, index: dict[str, ClassExtent]) -> str | None:
    """Modelica-style lookup of a (dotted) class name from inside class ``scope``."""
    head = name.split(".", 1)[0]
    parts = scope.split(".")
    for k in range(len(parts), -1, -1):
        prefix = ".".join(parts[:k])
        candidate_head = f"{prefix}.{head}" if prefix else head
        if candidate_head in index:
            full = f"{prefix}.{name}" if prefix else name
            return full if full in index else None
    return None


def used_classes(target: str, index: dict[str, ClassExtent]) -> set[str]:
    """Classes reachable from ``target`` through component types and extends clauses."""
    if target not in index:
        raise ModelicaError(f"class {target} not found; known models: {', '.join(sorted(_models(index)))}")
    seen, todo = set(), [target]
    while todo:
        cls = todo.pop()
        if cls in seen:
            continue
        seen.add(cls)
        for ref in index[cls].references:
            full = resolve(ref, cls, index)
            if full and full not in seen and index[full].kind != "package":
                todo.append(full)
    return seen


def model_sha256(source: PackageSource, target: str, index: dict[str, ClassExtent] | None = None) -> str:
    """Hash of what ``target`` is built from: the text of every class it uses and the
    text of their enclosing packages outside their classes (where constants and
    annotations live). Editing or adding another model leaves it unchanged, so only the
    models whose sources changed are rebuilt."""
    index = index if index is not None else class_index(source)
    used = used_classes(target, index)
    scopes = set(used)
    for name in used:
        parts = name.split(".")
        scopes.update(".".join(parts[:k]) for k in range(1, len(parts)))
    lines = source.text.splitlines(keepends=True)
    h = hashlib.sha256(target.encode())
    for name in sorted(scopes):
        ext = index.get(name)
        if ext is None:
            continue
        own = set(range(ext.first_line, ext.last_line + 1))
        if ext.kind == "package":  # its children are hashed as classes, if used
            for child, c in index.items():
                if child.startswith(name + ".") and c.first_line > ext.first_line:
                    own -= set(range(c.first_line, c.last_line + 1))
        h.update(f"\0{name}\0".encode())
        # blank lines between a package's classes change as classes come and go
        h.update("\n".join(t for k in sorted(own) if k - 1 < len(lines) and (t := lines[k - 1].strip())).encode())
    return h.hexdigest()


def _models(index: dict[str, ClassExtent]) -> list[str]:
    return [n for n, e in index.items() if e.kind == "model"]


def check_supported(source: PackageSource, target: str) -> None:
    """Raise :class:`UnsupportedConstruct` at the first construct the embedded path lacks."""
    index = class_index(source)
    used = used_classes(target, index)
    tokens = tokenize(source.text)
    problems = []
    for i, tok in enumerate(tokens):
        owner = _innermost(tok.line, index)
        if owner is None or owner.name not in used:
            continue
        what = _UNSUPPORTED_KEYWORDS.get(tok.text)
        nxt = tokens[i + 1].text if i + 1 < len(tokens) else ""
        prev = tokens[i - 1].text if i > 0 else ""
        if what is None and tok.text in _UNSUPPORTED_CALLS and nxt == "(" and prev != ".":
            what = _UNSUPPORTED_CALLS[tok.text]
        if what is None and tok.text == "if" and prev in {";", "equation", "then", "else", "loop"}:
            what = "if-equation (write an if-expression on the right-hand side)"
        if what:
            problems.append((tok.line, what, owner.name))
    if problems:
        line, what, owner = problems[0]
        more = f" ({len(problems) - 1} more)" if len(problems) > 1 else ""
        raise source.error(
            f"{what} in {owner} is not supported by the embedded compiler{more}; "
            "use the OpenModelica compiler or rewrite it", line, UnsupportedConstruct)


def _innermost(line: int, index: dict[str, ClassExtent]) -> ClassExtent | None:
    best = None
    for ext in index.values():
        if ext.first_line <= line <= ext.last_line:
            if best is None or ext.first_line >= best.first_line and ext.last_line <= best.last_line:
                best = ext
    return best


def find_call(source: PackageSource, target: str, function: str) -> int | None:
    """Line (assembled text) of the first call of ``function`` in classes used by ``target``."""
    index = class_index(source)
    used = used_classes(target, index)
    tokens = tokenize(source.text)
    for i, tok in enumerate(tokens[:-1]):
        if tok.text == function.rsplit(".", 1)[-1] and tokens[i + 1].text == "(":
            owner = _innermost(tok.line, index)
            if owner is not None and owner.name in used:
                return tok.line
    return None
