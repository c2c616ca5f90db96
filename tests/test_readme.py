"""Every Python example in README.md runs as written (in a scratch directory)."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib
import pytest

from conftest import VENDORED_DATA

README = Path(__file__).resolve().parents[1] / "README.md"
# The recording example reads files described in the README's TOML block:
# tests/test_nav_inspect.py writes them and runs that example.
BLOCKS = [
    b
    for b in re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    if "harbour.toml" not in b
]


def test_readme_has_examples():
    assert len(BLOCKS) >= 5


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_example_runs(index, tmp_path, monkeypatch):
    matplotlib.use("Agg")
    code = BLOCKS[index].replace("tests/data/", f"{VENDORED_DATA}/")
    monkeypatch.chdir(tmp_path)
    exec(compile(code, f"README.md python block {index}", "exec"), {"__name__": "readme"})
    assert Path.cwd() == tmp_path
