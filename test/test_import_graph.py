"""The package's import structure, computed with ``ast`` from the sources (tools/import_graph.py)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _tool():
    spec = importlib.util.spec_from_file_location("import_graph", ROOT / "tools" / "import_graph.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("import_graph", module)
    spec.loader.exec_module(module)
    return module


graph_tool = _tool()


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    """The package's imports, read from the sources once for the tests of this file."""
    return graph_tool.module_imports()


def _reachable(graph: dict[str, set[str]], start: str) -> set[str]:
    seen: set[str] = set()
    todo = [start]
    while todo:
        for t in graph[todo.pop()]:
            if t not in seen:
                seen.add(t)
                todo.append(t)
    return seen


def test_no_import_cycles(graph: dict[str, set[str]]) -> None:
    """No module imports itself around a circle, and inside no package do two parts import each other.

    Parts are a package's modules and its subpackages (each as a whole). Function-level imports
    count; type-only ones (``if TYPE_CHECKING:``) do not.
    """
    assert graph_tool.module_cycles(graph) == []
    assert graph_tool.cycles_within_packages(graph) == []


def test_cycle_finder_sees_function_level_imports(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    for folder in ("sub", "sub/inner", "other"):
        (pkg / folder).mkdir(parents=True)
        (pkg / folder / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "a.py").write_text("from pkg.sub.b import x\n")
    (pkg / "sub" / "b.py").write_text("def x():\n    from pkg.sub import a\n")
    type_only = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import a\n"
    (pkg / "sub" / "c.py").write_text(type_only)
    (pkg / "sub" / "inner" / "d.py").write_text("import pkg.sub.c\n")
    (pkg / "sub" / "e.py").write_text("def f():\n    from pkg.sub.inner import d\n")
    (pkg / "other" / "f.py").write_text("from pkg.sub.c import y\n")
    graph = graph_tool.module_imports(tmp_path, "pkg")
    assert graph["pkg.sub.b"] == {"pkg.sub.a"}
    assert graph["pkg.sub.c"] == set()  # type-only imports are never executed
    assert graph_tool.module_cycles(graph) == [["pkg.sub.a", "pkg.sub.b"]]
    # c -> inner (through d), and inner -> c: no module circle, but one between parts of pkg.sub
    assert ["pkg.sub.c", "pkg.sub.inner"] not in graph_tool.module_cycles(graph)
    assert sorted(graph_tool.cycles_within_packages(graph)) == [["pkg.sub.a", "pkg.sub.b"]]
    (pkg / "sub" / "c.py").write_text("def g():\n    from pkg.sub.inner import d\n")
    graph = graph_tool.module_imports(tmp_path, "pkg")
    assert ["pkg.sub.c", "pkg.sub.inner"] in graph_tool.cycles_within_packages(graph)


def test_live_replay_never_reaches_the_commands(graph: dict[str, set[str]]) -> None:
    """``bridge-shadow replay --live`` calls live replay, never the other way round.

    Live replay, the launcher and the node it launches import no command (not even through others).
    """
    assert "bridge_shadow.ros.live_replay" in graph["bridge_shadow.commands.replay"]
    for start in ("bridge_shadow.ros.live_replay", "bridge_shadow.ros.main", "bridge_shadow.ros.launcher"):
        reached = _reachable(graph, start)
        assert not {m for m in reached if m.startswith("bridge_shadow.commands") or m == "bridge_shadow.cli"}


def test_architecture_doc_is_current(graph: dict[str, set[str]]) -> None:
    """docs/architecture.md holds the graph the sources give (``python tools/import_graph.py``)."""
    text = graph_tool.DOC.read_text()
    assert graph_tool.BEGIN in text and graph_tool.END in text
    block = graph_tool.generated_block(graph=graph)
    assert graph_tool.render(text, block) == text, "run: python tools/import_graph.py"


def test_architecture_doc_draws_every_module(graph: dict[str, set[str]]) -> None:
    """Every module is a box in its package's graph, and every package has a graph."""
    block = graph_tool.generated_block(graph=graph)
    for pkg in graph_tool.packages(graph):
        for child in graph_tool.children_graph(graph, pkg):
            assert f'    {child.replace(".", "_")}["' in block
