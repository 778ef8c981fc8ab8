"""Helpers shared by the ``bench_*.py`` scripts: loading a module by path and median wall times."""

from __future__ import annotations

import importlib.util
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType


def load(name: str, path: Path) -> ModuleType:
    """Import the Python file ``path`` as module ``name`` (benchmarks and test fixtures are not packages)."""
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def median_s(func: Callable[[], object], repeats: int) -> float:
    """Median wall time of ``repeats`` calls of ``func`` (s)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def median_ms(func: Callable[[], object], repeats: int) -> float:
    """Median wall time of ``repeats`` calls of ``func`` (ms)."""
    return 1e3 * median_s(func, repeats)


def save_section(name: str, text: str) -> str:
    """Write a benchmark's Markdown section to ``benchmarks/results/<name>.md`` (what ``run_all.py``
    assembles into RESULTS.md) and return it; a benchmark run on its own keeps its numbers too."""
    section = text.rstrip() + "\n"
    results = Path(__file__).resolve().parent / "results"
    results.mkdir(exist_ok=True)
    (results / f"{name}.md").write_text(section)
    return section
