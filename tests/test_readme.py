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
