"""Helpers shared by the ``bench_*.py`` scripts: loading a module by path and median wall times."""

from __future__ import annotations

import importlib.util
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

# The benchmarks time studies set up from scratch: the study set-up cache (cadfeat.study.setup_cache) would make a
# second run read its set-up instead. Off here unless the caller says otherwise; bench_explore, which measures the
# cache, turns it on for its own starts.
os.environ.setdefault("CADFEAT_CACHE", "off")


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
