"""No import circle among the modules of ``hil.dut`` (issue 43: ``build`` <-> ``profile``).

A static check (``ast``, nothing imported): every ``import``/``from ... import`` of a ``hil.dut``
module's source, at the top, under ``if TYPE_CHECKING:`` or inside a function: a deferred import
is still a dependency, and a circle through one is two modules that cannot be read or changed
one without the other (the same rule as tests/hil/test_import_cycles.py for the other
packages). The package's own ``__init__``, which Python imports first, is not an edge.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = "hil.dut"
ROOT = Path(__file__).resolve().parents[3]


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(tree: ast.AST, module: str, is_package: bool) -> set[str]:
    """The modules ``tree`` imports, absolute, wherever the statement stands."""
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")
                base = base if is_package else base[:-1]
                base = base[:len(base) - (node.level - 1)]
                prefix = ".".join([*base, *([node.module] if node.module else [])])
            else:
                prefix = node.module or ""
            found.add(prefix)
            # "from hil.dut import build" imports the module hil.dut.build
            found.update(f"{prefix}.{alias.name}" for alias in node.names)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return found


def import_graph(package: str) -> dict[str, set[str]]:
    """Each module of ``package`` and the modules of ``package`` it imports."""
    directory = ROOT.joinpath(*package.split("."))
    modules = {_module_name(p): p for p in directory.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        targets = _imports(tree, name, path.name == "__init__.py")
        graph[name] = {t for t in targets if t in modules and t != name
                       and not name.startswith(t + ".") and t != package}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles of ``graph``: each strongly connected component of more than one
    module (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            strong(v)
    return sorted(found)


def test_the_checker_finds_a_circle_through_a_deferred_import(tmp_path: Path) -> None:
    a = ast.parse("from hil.dut.b import x\n")
    b = ast.parse("def f():\n    from hil.dut.a import y\n")
    graph = {"hil.dut.a": _imports(a, "hil.dut.a", False) & {"hil.dut.b"},
             "hil.dut.b": _imports(b, "hil.dut.b", False) & {"hil.dut.a"}}
    assert cycles(graph) == [["hil.dut.a", "hil.dut.b"]]
    typed = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                      "    from hil.dut.a import y\n")
    assert "hil.dut.a" in _imports(typed, "hil.dut.b", False)
    relative = ast.parse("from . import a\nfrom .b import c\n")
    assert {"hil.dut.a", "hil.dut.b"} <= _imports(relative, "hil.dut.x", False)


def test_the_graph_sees_the_package_as_it_is() -> None:
    graph = import_graph(PACKAGE)
    assert "hil.dut.profile" in graph and "hil.dut.build" in graph
    assert "hil.dut.profile" in graph["hil.dut.factory"]     # a real edge is seen


@pytest.mark.parametrize("package", [PACKAGE])
def test_no_import_circle(package: str) -> None:
    assert cycles(import_graph(package)) == []
