"""``rapid-cosim docs`` (issue 56): the documentation as an installed user has it, three
pages made from what is installed (config keys, test benches, standard structures)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rapid_cosim.cli import main
from rapid_cosim.cli.docs import MADE, page, pages
from rapid_cosim.experiment.schema import explain, reference_markdown

REPO = Path(__file__).resolve().parents[1]


def test_every_hand_written_page_ships_and_the_list_names_every_topic():
    assert set(pages()) == {p.stem for p in (REPO / "docs").glob("*.md")}
    listed = page(None)
    for topic in [*MADE, *pages()]:
        assert f"  {topic} " in listed


def test_the_made_pages_say_what_is_installed():
    assert page("config") == reference_markdown()
    benches = page("benches")
    assert "## `iGrGen.TestBenches.FrequencyInputTGOV1`" in benches
    section = benches.split("## `iGrGen.TestBenches.FrequencyInputTGOV1`")[1].split("## ")[0]
    assert "inputs: `f_dev` (Frequency: measured frequency minus nominal)" in section and "`pe`" in section
    staged = benches.split("## `iGrGen.TestBenches.StagedTest`")[1].split("## ")[0]
    assert "inputs: none (a staged test" in staged
    structures = page("structures")
    assert "## GAST" in structures and "estimates: R [0.02, 0.12], T1 [0.2, 3], T2 [0.02, 0.2]" in structures
    assert "optional, freed only where the data call for it: deadband (db [0, 0.002])" in structures
    formats = page("formats")
    assert formats.startswith("### The governor families and their layouts") and "TGOV1D" in formats


def test_an_unknown_topic_names_the_topics_and_errors_name_the_command(capsys):
    assert main(["docs", "nope"]) == 2
    assert "no page 'nope'; topics: config, benches" in capsys.readouterr().err
    assert "'rapid-cosim docs config' prints the page" in explain("data.outputs")


@pytest.mark.parametrize("topic", ["identify", "identify.md"])
def test_a_guide_prints_as_written(topic, capsys):
    assert main(["docs", topic]) == 0
    assert capsys.readouterr().out == (REPO / "docs" / "identify.md").read_text()
