"""The import graph: no cycles among the modules of reactive_anim/, tools/ and tests/; the shipped
package imports neither tools/ nor tests/, tools/ never imports tests/ (what both need is in
tools/devkit); and the core never imports Blender. Read from the source with ast (every import
statement, including those inside functions, so a lazy import cannot hide a cycle), not by
importing. And the physics engine has one seam in the core: only core/physics imports mujoco (the farm
reads its version for output fingerprints, nothing more)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.support.mocap import REPO

PACKAGES = ("reactive_anim", "tools", "tests")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for package in PACKAGES for p in sorted((REPO / package).rglob("*.py"))}


def _imports(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The project modules a module imports (absolute or relative, at any depth in the file)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            # `from . import x` imports the submodule x; `from .m import y` imports m.
            targets = [f"{base}.{alias.name}" for alias in node.names] + [base]
        else:
            continue
        found |= {t for t in targets if t in known and t != name}
    return found


def _graph() -> dict[str, set[str]]:
    known = _modules()
    return {name: _imports(name, path, known) for name, path in known.items()}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as a list of modules, or None (depth-first search with colours)."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_the_graph_sees_the_core_modules() -> None:
    """A check on the walker itself: the search depends on the library, which depends on Eq. 1."""
    graph = _graph()
    assert "reactive_anim.core.search.library" in graph["reactive_anim.core.search.search"]
    assert "reactive_anim.core.search.window" in graph["reactive_anim.core.search.library"]
    assert "reactive_anim.core.model.quat" in graph["reactive_anim.core.model.skeleton"]


def test_no_import_cycles() -> None:
    cycle = _cycle(_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


# Who may not import whom: the extension ships reactive_anim/ alone, and the tools are run without
# the tests (a benchmark on a machine that has only the repository's tools/).
FORBIDDEN = {"reactive_anim": ("tools", "tests"), "tools": ("tests",)}


def _breaches(graph: dict[str, set[str]]) -> list[str]:
    """The imports FORBIDDEN forbids, as "module -> module"."""
    return sorted(
        f"{name} -> {target}"
        for name, targets in graph.items()
        for target in targets
        if target.split(".")[0] in FORBIDDEN.get(name.split(".")[0], ())
    )


def test_the_layers_import_downwards_only() -> None:
    assert not _breaches(_graph())


def test_a_layer_breach_is_seen() -> None:
    """A check on the check: the tests importing tools is allowed, the other way round is not, and
    the walker sees the allowed edges in the real graph."""
    graph = {"tests.a": {"tools.b"}, "tools.b": {"tests.c"}, "reactive_anim.d": {"tools.b"}}
    assert _breaches(graph) == ["reactive_anim.d -> tools.b", "tools.b -> tests.c"]
    assert any(
        t.startswith("tools.") for name, targets in _graph().items() if name.startswith("tests.") for t in targets
    )


def test_a_cycle_is_found_when_there_is_one() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}
    assert _cycle(graph) == ["a", "b", "c", "a"]


@pytest.mark.parametrize("path", sorted((REPO / "reactive_anim" / "core").rglob("*.py")), ids=lambda p: p.name)
def test_the_core_never_imports_blender(path: Path) -> None:
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
        if isinstance(node, ast.ImportFrom):
            names = [node.module or ""]
        assert not any(n == "bpy" or n.startswith(("bpy.", "mathutils", "bmesh")) for n in names), path


def _third_party(path: Path) -> set[str]:
    """The top-level names of the absolute imports of a file (relative ones are the project's)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            found.add(node.module.split(".")[0])
    return found


def test_only_the_physics_package_imports_the_engine() -> None:
    physics = REPO / "reactive_anim" / "core" / "physics"
    engine_users = {p for p in (REPO / "reactive_anim" / "core").rglob("*.py") if "mujoco" in _third_party(p)}
    assert engine_users, "no module imports mujoco: the check reads nothing"
    assert {p.relative_to(REPO).as_posix() for p in engine_users if physics not in p.parents} == set()
