"""Every Python example in README.md and docs/*.md runs as written (in a scratch directory)."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib
import pytest

from conftest import VENDORED_DATA

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
# The recording example reads files described in the README's TOML block:
# tests/test_nav_inspect.py writes them and runs that example.
BLOCKS = [
    (f"{doc.relative_to(ROOT)} python block {i}", b)
    for doc in DOCS
    for i, b in enumerate(re.findall(r"```python\n(.*?)```", doc.read_text(), flags=re.S))
    if "harbour.toml" not in b
]


def test_docs_have_examples():
    assert sum(name.startswith("README.md") for name, _ in BLOCKS) >= 5
    assert sum(name.startswith("docs/") for name, _ in BLOCKS) >= 3


@pytest.mark.parametrize(("name", "code"), BLOCKS, ids=[name for name, _ in BLOCKS])
def test_doc_example_runs(name, code, tmp_path, monkeypatch):
    matplotlib.use("Agg")
    code = code.replace("tests/data/", f"{VENDORED_DATA}/")
    monkeypatch.chdir(tmp_path)
    exec(compile(code, name, "exec"), {"__name__": "readme"})
    assert Path.cwd() == tmp_path
