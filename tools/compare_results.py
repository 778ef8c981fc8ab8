#!/usr/bin/env python3
"""Compare two study results.json files: identical apart from the run-dependent keys?

    tools/compare_results.py BEFORE/results.json AFTER/results.json [--ignore KEY ...]

Run-dependent keys (``IGNORED``: the date ``created``, ``timings_s``, the package ``versions``) are left out;
``schema_version`` and ``cadfeat_version`` are compared unless ``--ignore``d (a deliberate layout change bumps
the schema version). Prints one line per differing dotted key (``objectives.after.g_FOV: 0.5 != 0.51``) and
exits 1 when any differs, 0 when the files agree. ``compare(a, b)`` is the same check as a function.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

__all__ = ["IGNORED", "compare", "compare_files", "main"]

IGNORED = ("created", "timings_s", "versions")
"""Top-level keys that differ between two runs of the same study by design (time and environment)."""


def _walk(a: Any, b: Any, key: str) -> Iterator[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            sub = f"{key}.{k}" if key else str(k)
            if k not in a:
                yield f"{sub}: only in the second"
            elif k not in b:
                yield f"{sub}: only in the first"
            else:
                yield from _walk(a[k], b[k], sub)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            yield f"{key}: {len(a)} items != {len(b)} items"
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            yield from _walk(x, y, f"{key}[{i}]")
    elif a != b or type(a) is not type(b):
        yield f"{key}: {a!r} != {b!r}"


def compare(a: dict[str, Any], b: dict[str, Any], ignore: Iterable[str] = IGNORED) -> list[str]:
    """The differing dotted keys of two results (``ignore``: top-level keys left out), as readable lines."""
    skip = set(ignore)
    return list(_walk({k: v for k, v in a.items() if k not in skip},
                      {k: v for k, v in b.items() if k not in skip}, ""))


def compare_files(a: str | Path, b: str | Path, ignore: Iterable[str] = IGNORED) -> list[str]:
    """``compare`` of two results.json files (a folder means its results.json)."""
    paths = [Path(p) / "results.json" if Path(p).is_dir() else Path(p) for p in (a, b)]
    return compare(*(json.loads(p.read_text(encoding="utf-8")) for p in paths), ignore=ignore)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("before", help="results.json (or its folder)")
    parser.add_argument("after", help="results.json (or its folder)")
    parser.add_argument("--ignore", action="append", default=[], metavar="KEY",
                        help=f"another top-level key to leave out (always: {', '.join(IGNORED)})")
    args = parser.parse_args(argv)
    diffs = compare_files(args.before, args.after, (*IGNORED, *args.ignore))
    for line in diffs:
        print(line)
    print(f"{'identical' if not diffs else f'{len(diffs)} difference(s)'} apart from "
          f"{', '.join((*IGNORED, *args.ignore))}")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
