#!/usr/bin/env python3
"""Move the test modules into sub-folders that mirror the package (tests/measures/, tests/cad/, …).

    tools/move_tests.py [--dry-run]

Re-runnable: after merging branches that edited or added tests, run it again and commit the result as one pure
move. For each ``tests/test_*.py`` it picks a folder (``folder_of``: an explicit table, then name prefixes; unknown
names stay in ``tests/``); a test already in a sub-folder moves only when the explicit table names another one
(``tests/study/test_study_cli.py`` → ``tests/cli/``: a module's tests sit in the folder of the sub-package they
test, ``tests/test_layout.py`` checks that every folder names one). It ``git mv``s the file, and rewrites the one
thing a move changes inside a test: paths computed from ``Path(__file__)`` (one folder deeper: ``.parent`` →
``.parents[1]``, ``.parents[1]`` → ``.parents[2]``). Mentions of moved tests (``tests/test_x.py``,
``tests/study/test_x.py``) in README.md, docs/, the package's docstrings, benchmarks and the tests themselves are
updated. The shared helpers and ``data/`` stay in ``tests/`` (``tests/conftest.py`` puts that folder on
``sys.path``); a test imports no other test module (they may sit in different folders).
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"

#: Tests whose folder is not given by their name's prefix.
EXPLICIT = {
    "test_compare_results": "study", "test_safety": "study", "test_trust_names": "study",
    "test_trust_objectives": "design", "test_trust_occlusion": "study", "test_trust_preflight": "study",
    "test_trust_foldover": "measures", "test_hole_identity": "cad", "test_occt_behaviour": "cad",
    "test_features": "cad", "test_parts": "cad", "test_redrill": "cad", "test_export": "cad",
    "test_design_map": "cad", "test_optimize": "design", "test_shop": "design", "test_robustness": "design",
    "test_patterns": "design", "test_camera": "", "test_poses": "", "test_package": "",
    "test_layout": "", "test_build_failures": "study", "test_start_independence": "study",
    "test_memory_budget": "design", "test_pose_objective": "design",
    "test_cqgi_parts": "cad", "test_real_step_parts": "cad", "test_explore": "explore",
    "test_explore_browser": "explore", "test_campaign": "campaign", "test_real_step_study": "study",
    "test_occt_real_exports": "cad", "test_outline_motion": "cad", "test_trajectory": "trajectory",
    "test_results_model": "results", "test_typed_sections": "results", "test_study_cli": "cli",
    "test_render_cli": "cli", "test_plan_recording": "cli", "test_docs": "",
}
#: Name prefix → folder, tried in order after ``EXPLICIT``.
PREFIXES = (("test_measures_", "measures"), ("test_step_", "cad"), ("test_optim_", "design"),
            ("test_study_", "study"), ("test_render_", "render"), ("test_report", "report"),
            ("test_vision_", "vision"), ("test_pose_", "measures"))

_FILE_PATH = re.compile(r"Path\(__file__\)(\.resolve\(\))?(\.parent\.parent|\.parents\[(\d)\]|\.parent)(?![\w\[])")


def folder_of(stem: str) -> str:
    """The sub-folder of ``tests/`` for a test module (``""``: stays in ``tests/``)."""
    if stem in EXPLICIT:
        return EXPLICIT[stem]
    return next((folder for prefix, folder in PREFIXES if stem.startswith(prefix)), "")


def deeper(text: str) -> str:
    """``Path(__file__)`` expressions of a file moved one folder down, pointing where they pointed before."""
    def repl(m: re.Match[str]) -> str:
        up = {".parent": 0, ".parent.parent": 1}.get(m.group(2))
        level = (int(m.group(3)) if up is None else up) + 1
        return f"Path(__file__){m.group(1) or ''}.parents[{level}]"
    return _FILE_PATH.sub(repl, text)


def plan() -> dict[Path, Path]:
    """Every test module not where it belongs, and where it goes (module docstring)."""
    moves = {}
    for path in sorted(TESTS.glob("test_*.py")):
        folder = folder_of(path.stem)
        if folder:
            moves[path] = TESTS / folder / path.name
    for path in sorted(TESTS.glob("*/test_*.py")):
        folder = EXPLICIT.get(path.stem)
        if folder and folder != path.parent.name:
            moves[path] = TESTS / folder / path.name
    return moves


def _mentions() -> list[Path]:
    """The files that may name a test module by its path."""
    files = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")), *sorted((ROOT / "cadfeat").rglob("*.py")),
             *sorted((ROOT / "benchmarks").rglob("*.py")), *sorted(TESTS.rglob("*.py"))]
    return [f for f in files if f.is_file()]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dry-run", action="store_true", help="print the moves only")
    args = parser.parse_args(argv)
    moves = plan()
    for src, dst in moves.items():
        print(f"{src.relative_to(ROOT)} -> {dst.relative_to(ROOT)}")
    if args.dry_run or not moves:
        return 0
    for src, dst in moves.items():
        dst.parent.mkdir(exist_ok=True)
        subprocess.run(["git", "mv", str(src), str(dst)], cwd=ROOT, check=True)
        if src.parent == TESTS:  # one folder deeper (a move between sub-folders keeps the depth)
            dst.write_text(deeper(dst.read_text(encoding="utf-8")), encoding="utf-8")
    names = {f"tests/{src.relative_to(TESTS).as_posix()}": f"tests/{dst.relative_to(TESTS).as_posix()}"
             for src, dst in moves.items()}
    pattern = re.compile("|".join(re.escape(k) for k in sorted(names, key=len, reverse=True)))
    for f in _mentions():
        text = f.read_text(encoding="utf-8")
        new = pattern.sub(lambda m: names[m.group(0)], text)
        if new != text:
            f.write_text(new, encoding="utf-8")
    subprocess.run(["git", "add", "-A", "tests", "README.md", "docs", "cadfeat", "benchmarks"], cwd=ROOT, check=True)
    print(f"{len(moves)} test modules moved; commit them as one pure move")
    return 0


if __name__ == "__main__":
    sys.exit(main())
