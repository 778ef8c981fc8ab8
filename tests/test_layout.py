"""The package layout (docs/design.md "Layout"): no import circle among cadfeat's modules, public names importable
at their homes, and the layout table of docs/design.md naming only paths that exist."""

from __future__ import annotations

import ast
import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "cadfeat"


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, modules: set[str]) -> set[str]:
    """cadfeat modules that ``path`` imports anywhere (module level or inside functions: a lazy import is still
    a dependency), with the packages they live in (importing ``a.b.c`` runs ``a.b``'s ``__init__`` too),
    except the importing module's own parents (already being imported)."""
    name = _module_name(path)
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{path}: relative import (the package uses absolute imports)"
            found.add(node.module or "")
            found.update(f"{node.module}.{a.name}" for a in node.names)
    out = set()
    for target in found:
        parts = target.split(".")
        out.update(".".join(parts[:i]) for i in range(1, len(parts) + 1))
    return {m for m in out if m in modules and m != name and not name.startswith(m + ".")}


def _graph() -> dict[str, set[str]]:
    paths = sorted(PACKAGE.rglob("*.py"))
    modules = {_module_name(p) for p in paths}
    return {_module_name(p): _imports(p, modules) for p in paths}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph`` (depth-first search), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def dfs(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := dfs(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := dfs(node)):
            return found
    return None


def test_cycle_finder_finds_a_planted_cycle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None


def test_no_import_circle_among_package_modules():
    graph = _graph()
    assert "cadfeat.cli" in graph and "cadfeat.cli.study" in graph["cadfeat.cli"]
    assert _cycle(graph) is None, f"import circle: {' -> '.join(_cycle(graph) or [])}"


@pytest.mark.parametrize("module, name", [
    ("cadfeat", "run_study"), ("cadfeat.study", "run_study"), ("cadfeat.study", "evaluate_study"),
    ("cadfeat.camera", "Camera"), ("cadfeat.measures", "evaluate"), ("cadfeat.measures", "image_jacobian"),
    ("cadfeat.measures", "hole_ellipse"), ("cadfeat.measures", "resolvability"),
    ("cadfeat.cad", "extract_holes"), ("cadfeat.cad", "load_step"), ("cadfeat.cad", "redrill"),
    ("cadfeat.cad", "load_part"), ("cadfeat", "extract_holes"), ("cadfeat", "load_step"), ("cadfeat", "redrill"),
    ("cadfeat", "load_part"),
])
def test_public_names_importable(module, name):
    assert callable(getattr(importlib.import_module(module), name))


def test_public_names_are_the_defining_functions():
    import cadfeat
    from cadfeat.cad.features import extract_holes
    from cadfeat.cad.step_parts import load_step

    assert cadfeat.extract_holes is extract_holes and cadfeat.load_step is load_step


def test_subpackages_stay_light():
    code = ("import sys, cadfeat.cad, cadfeat.design, cadfeat.study, cadfeat.cli; "
            "print('cadquery' in sys.modules, 'pyvista' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False"]


def test_design_layout_table_names_existing_paths():
    text = (ROOT / "docs" / "design.md").read_text()
    table = text[text.index("## Layout"):].split("\n## ")[0]
    rows = [line for line in table.splitlines() if line.startswith("| `")]
    assert rows
    for row in rows:
        first, what = row.split("|")[1:3]
        paths = re.findall(r"`([^`]+)`", first)
        folder = Path(paths[0]).parent if paths[0].endswith(".py") else Path(paths[0])
        for p in paths:
            cand = [ROOT / p, ROOT / folder / p, ROOT / "cadfeat" / p]
            assert any(c.exists() for c in cand), f"docs/design.md layout: {p} does not exist"
        prefix = Path(paths[0]) if paths[0].endswith("/") else None
        for p in re.findall(r"`([\w/]+(?:\.py|/))`", what):
            if prefix is not None:
                assert (ROOT / prefix / p).exists(), f"docs/design.md layout: {prefix / p} does not exist"
    listed = {re.findall(r"`([^`]+)`", r.split("|")[1])[0].rstrip("/") for r in rows}
    subpackages = {f"cadfeat/{p.name}" for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()}
    missing = {s for s in subpackages if not any(s == entry or s.startswith(entry + "/") or
                                                  s.split("/")[-1] + "/" in row for entry in listed for row in rows)}
    assert not missing, f"docs/design.md layout table misses {sorted(missing)}"


def _floor(module: str) -> str:
    """The sub-package a module belongs to (``cadfeat.cad.features.identity`` → ``cadfeat.cad``); a module at the
    package root is its own floor (``cadfeat.camera``)."""
    parts = module.split(".")
    return ".".join(parts[:2])


def test_no_import_circle_among_sub_packages():
    """The floors of the layout (docs/design.md "Layout") import downwards only: no loop between sub-packages (or root
    modules), counting lazy imports — an arrow up a floor (e.g. cad importing study) makes one."""
    graph: dict[str, set[str]] = {}
    for module, targets in _graph().items():
        if module == "cadfeat":
            continue  # the package's own __init__ re-exports the public names of every floor
        src = _floor(module)
        graph.setdefault(src, set()).update(_floor(t) for t in targets if t != "cadfeat" and _floor(t) != src)
    for node in list(graph.values()):
        for t in node:
            graph.setdefault(t, set())
    assert _cycle(graph) is None, f"import loop between sub-packages: {' -> '.join(_cycle(graph) or [])}"


def test_tests_mirror_the_package():
    """Tests mirror the package (issue 29 item 6): every sub-folder of tests/ with test modules names a sub-package
    or a module of cadfeat (tests/cli/ for cadfeat/cli/, tests/results/ for cadfeat/results/, …), so a module's
    tests are where a reader looks for them; tests/data holds fixtures only. A flat test module names no
    sub-package (``tools/move_tests.py`` moves the others)."""
    tests = ROOT / "tests"
    folders = sorted(p for p in tests.iterdir() if p.is_dir() and not p.name.startswith((".", "_")))
    assert folders
    for folder in folders:
        modules = sorted(folder.rglob("test_*.py"))
        if folder.name == "data":
            assert not modules, f"tests/data holds fixtures, not tests: {[m.name for m in modules]}"
            continue
        assert (PACKAGE / folder.name / "__init__.py").is_file() or (PACKAGE / f"{folder.name}.py").is_file(), \
            f"tests/{folder.name}/ names no sub-package or module of cadfeat"
    subpackages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()}
    for path in sorted(tests.glob("test_*.py")):
        assert path.stem.removeprefix("test_") not in subpackages, \
            f"tests/{path.name} tests cadfeat/{path.stem.removeprefix('test_')}/: it belongs in that folder"
