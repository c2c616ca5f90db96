"""The hand-written stub `_core.pyi` must match the native module, name for name."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

from usvfast import _core

STUB = Path(__file__).resolve().parents[1] / "python" / "usvfast" / "_core.pyi"


def _stub_items() -> dict[str, ast.AST]:
    tree = ast.parse(STUB.read_text())
    items: dict[str, ast.AST] = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            items[node.name] = node
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            items[node.target.id] = node
    return items


def _runtime_names() -> set[str]:
    return {n for n in dir(_core) if not n.startswith("_")} | {"__version__"}


def _stub_params(fn: ast.FunctionDef) -> list[tuple[str, str]]:
    a = fn.args
    params = [(p.arg, "positional") for p in a.posonlyargs + a.args]
    params += [(p.arg, "keyword") for p in a.kwonlyargs]
    return [p for p in params if p[0] not in ("self", "cls")]


def _runtime_params(obj) -> list[tuple[str, str]]:
    sig = inspect.signature(obj)
    kinds = {
        inspect.Parameter.POSITIONAL_ONLY: "positional",
        inspect.Parameter.POSITIONAL_OR_KEYWORD: "positional",
        inspect.Parameter.KEYWORD_ONLY: "keyword",
    }
    return [
        (p.name, kinds.get(p.kind, str(p.kind)))
        for p in sig.parameters.values()
        if p.name not in ("self", "cls")
    ]


def test_every_runtime_name_has_a_stub_and_back():
    stub = set(_stub_items())
    runtime = _runtime_names()
    assert runtime - stub == set(), "names without a stub in _core.pyi"
    assert stub - runtime == set(), "stubs naming something _core does not have"


@pytest.mark.parametrize("name", sorted(_runtime_names()))
def test_signatures_match(name):
    node = _stub_items()[name]
    obj = getattr(_core, name)
    if isinstance(node, ast.FunctionDef):
        assert _stub_params(node) == _runtime_params(obj)
    elif isinstance(node, ast.ClassDef):
        assert inspect.isclass(obj)
        stub_members = {
            n.name
            for n in node.body
            if isinstance(n, ast.FunctionDef) and not n.name.startswith("_")
        } | {
            n.target.id
            for n in node.body
            if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name)
        }
        runtime_members = {m for m in vars(obj) if not m.startswith("_")}
        assert stub_members == runtime_members
        for n in node.body:
            if isinstance(n, ast.FunctionDef) and not n.name.startswith("_"):
                if any(getattr(d, "id", None) == "property" for d in n.decorator_list):
                    assert inspect.isdatadescriptor(vars(obj)[n.name])
                    continue
                assert _stub_params(n) == _runtime_params(getattr(obj, n.name))
