"""The README is a front page and the docs stay true: every page is reachable from the
index, every link lands, every make target and CLI command the docs name exists, and
every make target is in the guide."""

import argparse
import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
PAGES = sorted(DOCS.glob("*.md"))
TEXTS = [REPO / "README.md", *PAGES]


def _targets() -> set[str]:
    """The Makefile's targets as ``make help`` lists them (test1..test10 spelled out)."""
    out = subprocess.run(["make", "-s", "--no-print-directory", "help"], cwd=REPO, capture_output=True, text=True,
                         check=True).stdout
    names = set()
    for line in out.splitlines():
        m = re.match(r"\s*make (\S+)", line)
        if m:
            names.update(f"test{k}" for k in range(1, 11)) if m.group(1) == "test1..test10" else names.add(m.group(1))
    return names


def _commands() -> set[str]:
    from rapid_cosim.cli.parser import build_parser

    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return set(sub.choices)


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    """Headings' anchors, and explicit ones (``<a id="data.delimiter"></a>``, docs/config.md's keys)."""
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    return ({_slug(m.group(1)) for m in re.finditer(r"^#+ (.+)$", text, flags=re.M)}
            | set(re.findall(r'<a id="([^"]+)"></a>', text)))


def test_the_readme_is_a_front_page_with_two_commands_first():
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= 250, len(lines)
    first_screen = "\n".join(lines[:20])
    assert re.findall(r"^\s+make (\w+)", first_screen, flags=re.M) == ["demo", "test"]


def test_every_page_is_linked_from_the_index_and_the_index_from_the_readme():
    index = (DOCS / "index.md").read_text()
    unlinked = [p.name for p in PAGES if p.name != "index.md" and f"]({p.name}" not in index]
    assert not unlinked, f"docs pages not linked from docs/index.md: {unlinked}"
    assert "](docs/index.md)" in (REPO / "README.md").read_text()


@pytest.mark.parametrize("path", TEXTS, ids=lambda p: p.name)
def test_every_relative_link_lands(path):
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    broken = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+://", target):
            continue
        file, _, anchor = target.partition("#")
        dest = (path.parent / file).resolve() if file else path
        if not dest.exists():
            broken.append(target)
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            broken.append(target)
    assert not broken, f"{path.name}: links that do not land: {broken}"


def test_every_make_target_the_docs_name_exists_and_every_target_is_in_the_guide():
    targets = _targets()
    named = set()
    for path in TEXTS:
        # as code: `make X` or an indented command line (prose says "make targets")
        named.update(n for n in re.findall(r"(?:`|^\s+)make ([a-z][\w-]*)", path.read_text(), flags=re.M)
                     if not n.endswith("-"))  # `make bench-*`: the family
    unknown = sorted(named - targets)
    assert not unknown, f"make targets named in the docs that the Makefile lacks: {unknown}"
    guide = "\n".join(p.read_text() for p in PAGES)
    missing = sorted(t for t in targets if f"make {t}" not in guide and not re.fullmatch(r"test\d+", t))
    assert not missing, f"make targets not in the guide: {missing}"


def test_every_cli_command_the_docs_name_exists():
    commands = _commands()
    named = set()
    for path in TEXTS:
        named.update(re.findall(r"(?:`|^\s+|bin/)rapid-cosim ([a-z][\w-]*)", path.read_text(), flags=re.M))
    unknown = sorted(named - commands)
    assert not unknown, f"rapid-cosim commands named in the docs that the CLI lacks: {unknown}"


def test_the_check_finds_a_broken_link_and_an_unknown_target(tmp_path):
    page = tmp_path / "p.md"
    page.write_text("# Title\n[x](missing.md) [y](#title) [z](#nope)\n")
    text = page.read_text()
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    bad = [t for t in links if (t.partition("#")[0] and not (tmp_path / t.partition("#")[0]).exists())
           or (t.startswith("#") and t[1:] not in _anchors(page))]
    assert bad == ["missing.md", "#nope"]
    assert "bench-nothing" not in _targets() and "test10" in _targets()


def test_every_source_file_the_docs_name_exists():
    named = set()
    for path in TEXTS:
        named.update(re.findall(r"\b((?:rapid_cosim|benchmarks|tests|experiments)/[\w/]+\.(?:py|toml))\b",
                                path.read_text()))
    missing = sorted(n for n in named if not (REPO / n).exists())
    assert not missing, f"files named in the docs that are not there: {missing}"
