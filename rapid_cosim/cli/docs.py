"""``rapid-cosim docs [TOPIC]``: the documentation as an installed user has it. The
hand-written pages ship inside the package (``rapid_cosim/pages``, the repository's
``docs/``); three are made from what is installed, so they cannot drift from it: the
config keys (``config``, from the schema), the test benches (``benches``, from the
Modelica package) and the standard structures (``structures``, from the shipped files).
``formats`` is the families-and-layouts part of the identify page."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ..compiler.source import ModelSource
from ..errors import ConfigError

MADE = {"config": "every key of a config, a unit, a fleet, a structure and a tolerance file",
        "benches": "every test bench: what it is for, its inputs and outputs",
        "structures": "the standard structures: what each estimates, its optional parts, which plants get it",
        "formats": "the governor families and the record layouts read and written, and where each is checked"}
_FORMATS = ("### The governor families and their layouts", "## The validation report")


def pages() -> dict[str, Path]:
    """The shipped hand-written pages by name."""
    folder = Path(str(resources.files("rapid_cosim") / "pages"))
    return {p.stem: p for p in sorted(folder.glob("*.md"))}


def page(topic: str | None, source: ModelSource = ModelSource()) -> str:
    """The text of a topic, or without one the list of topics."""
    written = pages()
    if topic is None:
        lines = ["topics (rapid-cosim docs TOPIC):"]
        lines += [f"  {name:<12} {what}" for name, what in MADE.items()]
        lines += [f"  {name:<12} {_title(path)}" for name, path in written.items() if name not in MADE]
        return "\n".join(lines) + "\n"
    if topic == "config":
        from ..experiment.schema import reference_markdown

        return reference_markdown()
    if topic == "benches":
        from ..compiler.benches import benches_page

        return benches_page(source.check().package_path) + "\n"
    if topic == "structures":
        from ..structures.page import structures_page

        return structures_page() + "\n"
    if topic == "formats":
        text = written["identify"].read_text(encoding="utf-8")
        start = text.index(_FORMATS[0])
        return text[start:text.index(_FORMATS[1], start)]
    name = topic.removesuffix(".md")
    if name not in written:
        raise ConfigError(f"no page {topic!r}; topics: {', '.join([*MADE, *(n for n in written if n not in MADE)])}",
                          None, None)
    return written[name].read_text(encoding="utf-8")


def _title(path: Path) -> str:
    first = path.read_text(encoding="utf-8").lstrip().splitlines()[0]
    return first.lstrip("# ").strip()


def cmd_docs(args) -> int:
    print(page(args.topic, ModelSource(args.package, args.fmus, args.compiler)), end="")
    return 0


def cmd_example(args) -> int:
    """``rapid-cosim example [NAME [DIR]]``: the list, or one copied out."""
    from ..examples import EXAMPLES, copy_example

    if args.name is None:
        print("examples (rapid-cosim example NAME [DIR]; copied into ./NAME by default):")
        for name, ex in EXAMPLES.items():
            print(f"  {name:<13} {ex.what}")
        return 0
    folder, copied = copy_example(args.name, args.dir)
    ex = EXAMPLES[args.name]
    print(f"{folder}: {'copied' if copied else 'there already, left as it is'} ({ex.what})")
    print(f"next: {ex.try_it.replace(f' {args.name}', f' {folder}', 1)}")
    return 0
