"""No import circles inside the packages a newcomer reads first (issue 43).

A static check over the source (``ast``, nothing is imported): within one package, module A
*depends on* module B when A has an import statement naming B, wherever the statement stands:

- at module level (the interpreter runs it at import),
- under ``if TYPE_CHECKING:`` (only the type checker runs it, but the reader of A must know B),
- inside a function (run when the function is first called: a circle the interpreter tolerates
  because the import is late, not one that is absent).

A *cycle* is a set of two or more modules each of which depends, directly or through the
others, on every other one (a strongly connected component of that graph). All three kinds of
import count alike: a circle hidden from the interpreter by ``TYPE_CHECKING`` or a late import is
still two modules that cannot be read, tested or changed one without the other. The message
names each edge of a cycle with its kind (``module``, ``typing``, ``function``), so the way out
is visible: a ``Protocol`` in the module that needs a role instead of an import of the class that
plays it, or the shared piece moved to a module both import.

``from pkg import name`` depends on ``pkg.name`` when that is a module of the package, else on
the package's ``__init__`` (which runs whatever ``__init__`` imports).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: the packages kept free of cycles (issue 43: the qualification session, the software bus,
#: the rig's runner and its checkpoints)
PACKAGES = ("hil.softbus", "hil.rig", "hil.qualification")

Edge = tuple[str, str]          # (target module, kind: module | typing | function)


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(tree: ast.Module) -> Iterator[tuple[ast.Import | ast.ImportFrom, str]]:
    """Every import statement of a module with where it stands (module, typing, function)."""
    def walk(node: ast.AST, kind: str) -> Iterator[tuple[ast.Import | ast.ImportFrom, str]]:
        for child in ast.iter_child_nodes(node):
            here = kind
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                here = "function"
            elif (isinstance(child, ast.If) and kind == "module"
                  and "TYPE_CHECKING" in ast.unparse(child.test)):
                here = "typing"
            if isinstance(child, ast.Import | ast.ImportFrom):
                yield child, here
            yield from walk(child, here)
    yield from walk(tree, "module")


def import_graph(package_dir: Path, root: Path) -> dict[str, set[Edge]]:
    """The package's modules and, for each, the modules of the same package it depends on."""
    paths = {_module_name(p, root): p for p in sorted(package_dir.glob("*.py"))}
    graph: dict[str, set[Edge]] = {}
    for name, path in paths.items():
        is_init = path.name == "__init__.py"
        edges: set[Edge] = set()
        for stmt, kind in _imports(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            targets: list[str] = []
            if isinstance(stmt, ast.Import):
                targets = [a.name for a in stmt.names]
            else:
                base = stmt.module or ""
                if stmt.level:       # relative: from the module's own package upwards
                    package = name.split(".") if is_init else name.split(".")[:-1]
                    package = package[:len(package) - (stmt.level - 1)]
                    base = ".".join(package + ([base] if base else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in paths else base
                           for a in stmt.names]
            edges |= {(t, kind) for t in targets if t in paths and t != name}
        graph[name] = edges
    return graph


def cycles(graph: dict[str, set[Edge]]) -> list[list[str]]:
    """The strongly connected components of two or more modules (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target, _kind in sorted(graph[node]):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return sorted(found)


def describe(graph: dict[str, set[Edge]], component: list[str]) -> str:
    """The edges inside one cycle, each with its kind of import."""
    inside = set(component)
    return "; ".join(f"{a} -> {b} ({kind})" for a in component
                     for b, kind in sorted(graph[a]) if b in inside)


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_cycle_in_the_package(package: str) -> None:
    graph = import_graph(ROOT / package.replace(".", "/"), ROOT)
    assert len(graph) > 1, f"{package}: no modules found"
    found = cycles(graph)
    assert not found, f"{package}: import cycles: " + " | ".join(
        describe(graph, c) for c in found)


# --- the check itself can fail ---------------------------------------------------------------
def _package(root: Path, files: dict[str, str]) -> Path:
    pkg = root / "pkg"
    pkg.mkdir()
    for name, text in {"__init__.py": "", **files}.items():
        (pkg / name).write_text(text, encoding="utf-8")
    return pkg


def test_a_cycle_through_a_typing_and_a_late_import_is_found(tmp_path: Path) -> None:
    pkg = _package(tmp_path, {
        "a.py": "from pkg.b import B\n",
        "b.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.c import C\n",
        "c.py": "def f():\n    from . import a\n",
        "d.py": "from pkg import a\n",          # depends on the cycle, is not in it
    })
    graph = import_graph(pkg, tmp_path)
    assert cycles(graph) == [["pkg.a", "pkg.b", "pkg.c"]]
    assert describe(graph, ["pkg.a", "pkg.b", "pkg.c"]) == (
        "pkg.a -> pkg.b (module); pkg.b -> pkg.c (typing); pkg.c -> pkg.a (function)")


def test_a_package_importing_one_way_has_no_cycle(tmp_path: Path) -> None:
    pkg = _package(tmp_path, {
        "a.py": "from pkg.b import B\nfrom pkg import c\n",
        "b.py": "import pkg.c\n",
        "c.py": "import json\n",
    })
    graph = import_graph(pkg, tmp_path)
    assert graph["pkg.a"] == {("pkg.b", "module"), ("pkg.c", "module")}
    assert cycles(graph) == []


def test_importing_a_name_of_the_package_depends_on_its_init(tmp_path: Path) -> None:
    """``from pkg import A`` (a name ``__init__`` re-exports) runs ``__init__``: a cycle when
    ``__init__`` imports the importer."""
    pkg = _package(tmp_path, {"a.py": "from pkg import B\n", "b.py": "B = 1\n"})
    (pkg / "__init__.py").write_text("from pkg.a import *\nfrom pkg.b import B\n")
    assert cycles(import_graph(pkg, tmp_path)) == [["pkg", "pkg.a"]]
