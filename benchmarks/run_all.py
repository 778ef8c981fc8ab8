"""Run every ``benchmarks/bench_*.py`` and assemble ``benchmarks/RESULTS.md``.

Convention: each benchmark module defines ``main(quick: bool = False) -> str`` that measures, returns a
Markdown section (a ``## Title``, a table, the baseline ratio) and writes it to
``benchmarks/results/<module>.md`` with ``benchutil.save_section``. ``python benchmarks/run_all.py
[name ...]`` re-runs the named benchmarks (all by default); sections of benchmarks not re-run are kept
from their last run.
"""

from __future__ import annotations

import importlib.util
import os
import platform
import sys
from datetime import UTC, datetime
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "RESULTS.md"
SECTIONS = HERE / "results"


def machine_description() -> str:
    """One line naming the machine the numbers were measured on."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numpy

    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {numpy.__version__}, "
            f"{platform.system()} {platform.release()}")


def run(names: list[str]) -> None:
    SECTIONS.mkdir(exist_ok=True)
    scripts = sorted(HERE.glob("bench_*.py"))
    chosen = [s for s in scripts if not names or s.stem in names or s.stem.removeprefix("bench_") in names]
    for script in chosen:
        spec = importlib.util.spec_from_file_location(script.stem, script)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        print(f"== {script.stem}", flush=True)
        module.main()  # writes its section to results/<name>.md (benchutil.save_section)
    body = [
        "# Benchmark results",
        "",
        "Written by `make bench` (`benchmarks/run_all.py`). Each section states its machine and the ratio",
        "to a baseline measured in the same run. Last assembled "
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC on: {machine_description()}.",
        "",
    ]
    for path in sorted(SECTIONS.glob("bench_*.md")):
        body += [path.read_text().rstrip(), ""]
    RESULTS.write_text("\n".join(body))
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    run(sys.argv[1:])
