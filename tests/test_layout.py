"""The three wings and the direction of their imports (architecture: engine, geometry library, node library)."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

PKG = Path(__file__).resolve().parent.parent / "sengine"


def _module(path: Path) -> str:
    parts = path.relative_to(PKG.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_module(name: str) -> bool:
    path = PKG.parent.joinpath(*name.split("."))
    return path.with_suffix(".py").exists() or (path / "__init__.py").exists()


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(path: Path) -> set[str]:
    """Every sengine module ``path`` imports, at any level of the file (function-level imports too)."""
    mod = _module(path)
    package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    out = set()
    tree = ast.parse(path.read_text())
    typing_only = {
        id(n)
        for block in ast.walk(tree)
        if isinstance(block, ast.If) and _is_type_checking(block.test)
        for stmt in block.body
        for n in ast.walk(stmt)
    }
    for node in ast.walk(tree):
        if id(node) in typing_only:  # ``if TYPE_CHECKING:`` imports never run
            continue
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == "sengine"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "sengine":
                continue
            out.add(target)
            out |= {f"{target}.{a.name}" for a in node.names if _is_module(f"{target}.{a.name}")}
    return out


GRAPH = {_module(p): _imports(p) for p in sorted(PKG.rglob("*.py"))}


def _wing(mod: str) -> str:
    if mod == "sengine.nodes" or mod.startswith("sengine.nodes."):
        return "nodes"
    if mod == "sengine.geom" or mod.startswith("sengine.geom."):
        return "geom"
    return "engine"


def test_the_three_wings_exist():
    wings = {_wing(m) for m in GRAPH}
    assert wings == {"engine", "geom", "nodes"}
    assert not (PKG.parent / "nodes").exists() and not (PKG.parent / "networks").exists()


def test_nothing_outside_the_node_library_imports_it():
    bad = sorted((m, t) for m, ts in GRAPH.items() for t in ts if _wing(m) != "nodes" and _wing(t) == "nodes")
    assert not bad, bad


def test_the_geometry_library_imports_only_itself_and_the_errors():
    bad = sorted(
        (m, t)
        for m, ts in GRAPH.items()
        for t in ts
        if _wing(m) == "geom" and _wing(t) != "geom" and t not in ("sengine.errors", "sengine")
    )
    assert not bad, bad
    # ``from sengine import X`` would load the whole engine
    assert not [m for m, ts in GRAPH.items() if _wing(m) == "geom" and "sengine" in ts]


def test_no_import_circle():
    g = nx.DiGraph()
    for m, ts in GRAPH.items():
        for t in ts:
            if t in GRAPH and t != m and not m.startswith(t + "."):  # a package's own __init__ is its parent
                g.add_edge(m, t)
    cycles = list(nx.simple_cycles(g))
    assert not cycles, cycles[:5]
