"""The README's Python snippets run as written (issue 12: its API example did not)."""
import os
import re

from tests.conftest import ROOT


def python_blocks():
    text = (ROOT / "README.md").read_text()
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_readme_python_snippets_run(tmp_path, monkeypatch):
    blocks = python_blocks()
    assert len(blocks) >= 2  # the quick start and the API section
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)  # the snippets write out.csv, out.png into the working folder
    for code in blocks:
        exec(compile(code, "README.md", "exec"), {})
    assert (tmp_path / "out.csv").exists() and (tmp_path / "out.png").exists()
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".")]  # no temporaries left
