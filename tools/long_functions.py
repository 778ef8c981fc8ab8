#!/usr/bin/env python3
"""List functions longer than a limit (source lines, decorators and docstring included), longest first.

    tools/long_functions.py [PATH ...] [--max 80]

Exits 1 when any function is over the limit (so it can guard a folder), 0 otherwise.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections.abc import Iterator
from pathlib import Path

__all__ = ["long_functions", "main"]


def _functions(path: Path) -> Iterator[tuple[int, str, int]]:
    """(length, qualified name, first line) of every function and method in ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    stack: list[tuple[ast.AST, str]] = [(tree, "")]
    while stack:
        node, prefix = stack.pop()
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                name = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    first = min([child.lineno, *(d.lineno for d in child.decorator_list)])
                    yield (child.end_lineno or child.lineno) - first + 1, name, first
                stack.append((child, f"{name}."))
            else:
                stack.append((child, prefix))


def long_functions(paths: list[Path], limit: int) -> list[tuple[int, str]]:
    """(length, ``file:line name``) of functions over ``limit`` lines under ``paths``, longest first."""
    files = [f for p in paths for f in (sorted(p.rglob("*.py")) if p.is_dir() else [p])]
    found = [(n, f"{f}:{line} {name}") for f in files for n, name, line in _functions(f) if n > limit]
    return sorted(found, reverse=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="*", type=Path, default=[Path("cadfeat")])
    parser.add_argument("--max", type=int, default=80, help="longest allowed function (lines)")
    args = parser.parse_args(argv)
    found = long_functions(args.paths, args.max)
    for n, where in found:
        print(f"{n:5d}  {where}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
