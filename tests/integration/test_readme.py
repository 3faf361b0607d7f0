"""The README's user-facing Python snippets (quick start, Python API) run as written (issue 12:
its API example did not). Fragments in the reference sections (design studies, SIMD kernel) are
illustrations with free names and are not run here."""
import os
import re

from tests.conftest import ROOT

RUN_SECTIONS = ("Quick start", "Python API")


def python_blocks(sections=RUN_SECTIONS):
    text = (ROOT / "README.md").read_text()
    blocks = []
    for part in re.split(r"^## ", text, flags=re.M)[1:]:
        if part.startswith(sections):
            blocks += re.findall(r"```python\n(.*?)```", part, flags=re.S)
    return blocks


def test_readme_python_snippets_run(tmp_path, monkeypatch):
    blocks = python_blocks()
    assert len(blocks) >= 2  # the quick start and the API section
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)  # the snippets write out.csv, out.png into the working folder
    for code in blocks:
        exec(compile(code, "README.md", "exec"), {})
    assert (tmp_path / "out.csv").exists() and (tmp_path / "out.png").exists()
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".")]  # no temporaries left
