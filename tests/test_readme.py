"""The README's Python example runs as written, from an empty folder (issue 56: it needed
the repository's experiments/ until the examples shipped)."""

import re

import matplotlib

matplotlib.use("Agg")


def test_the_python_example_of_the_readme_runs(repo, fmus, monkeypatch, tmp_path, capsys):
    text = (repo / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    example = next(b for b in blocks if "import rapid_cosim" in b)
    lines = [ln for ln in example.splitlines() if ln.strip() and not ln.strip().startswith("#")]
    assert len(lines) < 10, "the example promises fewer than 10 lines of user code"
    user = tmp_path / "user"
    user.mkdir()
    monkeypatch.chdir(user)
    monkeypatch.setenv("TMPDIR", str(tmp_path))  # the run's archive goes to a temporary folder
    figure = user / "results" / "test1-fit.png"
    exec(compile(example, "README.md", "exec"), {})
    out = capsys.readouterr().out
    assert "method pf:10+nm: best fitness" in out and out.rstrip().endswith("True")
    assert figure.exists() and figure.stat().st_size > 10_000
    assert (user / "test1" / "config.toml").is_file()  # rc.example copied it there


def _figures(text: str) -> list[str]:
    """The measured figures of a text: times, shares, memory, counts 'N of M', speed-ups."""
    pattern = (r"\d[\d,]*(?:\.\d+)?\s(?:%|min|minutes|ms|s|MB|GB)(?![\w/])|\d+ of \d+|\d+/\d+|x\d+"
               r"|\d+(?:\.\d+)? times")
    return sorted(set(re.findall(pattern, text)))


def test_every_figure_the_readme_states_is_in_the_studies(repo):
    """Issue 56: one figure per thing, from the last benchmark run: the README's headline
    table, its costs and its timings appear in docs/studies.md (or, for the field unit's
    story, in docs/identify.md) as stated."""
    readme = (repo / "README.md").read_text()
    studies = " ".join((repo / "docs" / "studies.md").read_text().split())
    identify = " ".join((repo / "docs" / "identify.md").read_text().split())
    headline = readme.split("## Headline figures")[1].split("\n## ")[0]
    cost = readme[readme.index("Cost on 2 cores"):].split("\n\n")[0]
    timings = re.findall(r"#\s*about [^\n]*", readme)
    stated = _figures(" ".join(" ".join(part.split()) for part in (headline, cost, *timings)))
    assert len(stated) > 10, stated  # the check reads figures at all
    missing = [f for f in stated if f not in studies and f not in identify]
    assert not missing, f"README figures not in docs/studies.md or docs/identify.md: {missing}"
