"""The command line of a generated documentation page (``tools/gen_*_reference.py``): write it, print it
(``--stdout``) or check that the committed page is the generator's output (``--check``, exit 1 otherwise)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path


def page_main(argv: list[str], generate: Callable[[], str], page: Path, root: Path, script: str) -> int:
    """Run the generator ``generate`` for ``page`` (under ``root``) as ``argv`` asks; ``script`` names it."""
    text = generate()
    if "--stdout" in argv:
        print(text, end="")
    elif "--check" in argv:
        if not page.is_file() or page.read_text(encoding="utf-8") != text:
            print(f"{page.relative_to(root)} is out of date: run python tools/{script}")
            return 1
    else:
        page.parent.mkdir(parents=True, exist_ok=True)
        page.write_text(text, encoding="utf-8")
        print(page.relative_to(root))
    return 0
