"""The examples that ship (issue 56): each copies out whole and self-contained, a second
copy leaves the user's folder alone, and the copies pass ``check`` from any folder."""

from __future__ import annotations

from pathlib import Path

import pytest

import rapid_cosim as rc
from rapid_cosim.errors import ConfigError
from rapid_cosim.examples import EXAMPLES, copy_example, examples_root

REPO = Path(__file__).resolve().parents[1]


def test_every_example_copies_out_self_contained(tmp_path):
    assert examples_root().resolve() == (REPO / "experiments").resolve()
    for name in EXAMPLES:
        folder, copied = copy_example(name, tmp_path / name)
        assert copied and any(folder.iterdir())
        assert not list(folder.rglob("*.py")), name  # the generators stay in the repository
        for unit in folder.rglob("unit.toml"):
            assert '"../' not in unit.read_text(), unit
    assert (tmp_path / "staged-tests" / "structures" / "TGOV1.toml").is_file()  # the link, copied as files
    steam = (tmp_path / "steam" / "unit.toml").read_text()
    assert 'files = ["structures/TGOV1.toml", "structures/IEEEG1.toml"]' in steam
    assert (tmp_path / "steam" / "structures" / "IEEEG1.toml").read_text() == \
        (REPO / "experiments" / "electrical" / "structures" / "IEEEG1.toml").read_text()


def test_a_second_copy_leaves_the_folder_alone_and_bad_names_are_said(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    folder = rc.example("test1")
    assert folder == Path("test1") and (tmp_path / "test1" / "test1.csv").is_file()
    (folder / "config.toml").write_text("# the user's edit\n")
    assert copy_example("test1") == (Path("test1"), False)
    assert (folder / "config.toml").read_text() == "# the user's edit\n"
    with pytest.raises(ConfigError, match="no example 'tset1'; the examples: test1, staged-tests"):
        rc.example("tset1")
    (tmp_path / "afile").write_text("")
    with pytest.raises(ConfigError, match="is a file"):
        rc.example("test1", tmp_path / "afile")


def test_the_copied_steam_unit_passes_check_elsewhere(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    report = rc.check(rc.example("steam") / "unit.toml")
    assert report.ok, report.text()
