"""Test-suite set-up: the shared helpers of ``tests/`` (``study_helpers``, ``optim_helpers``, ``report_fixture``,
``report_html``) importable from the sub-folders that mirror the package (tests/cad/, tests/study/, …)."""

from __future__ import annotations

import sys
from pathlib import Path

_TESTS = str(Path(__file__).resolve().parent)
if _TESTS not in sys.path:
    sys.path.insert(0, _TESTS)

# cadfeat run's closed-loop check (study.closed_loop_check) renders and tracks both designs: on by default for
# users, off for the suite's many small studies that do not test it (a test that does sets [tracking] check).
import os  # noqa: E402

os.environ.setdefault("CADFEAT_TRACKING_CHECK", "off")
# The study set-up cache (study.setup_cache) is off for the suite: each test sets its studies up itself (and
# nothing is written into the user's cache folder); the tests of the cache turn it on with a folder of their own.
os.environ.setdefault("CADFEAT_CACHE", "off")


#: The folders whose every test is numerical (measures, optimisers and robust design, vision, the cell's models): all
#: of them run again in `make test`'s kernel pass (Makefile ``test-kernels``: another OpenBLAS kernel family), not
#: only the files that say ``pytestmark = pytest.mark.numerics`` — a decision that flips on round-off (a tie, a
#: stopping test, a derivative-free path) can hide in any of them (issue 32 item 8: the razor-edge robust test).
NUMERICS_FOLDERS = ("measures", "design", "vision", "cell")


def pytest_collection_modifyitems(items):
    import pytest

    root = Path(__file__).resolve().parent
    folders = tuple(root / name for name in NUMERICS_FOLDERS)
    for item in items:
        path = Path(str(item.path)).resolve()
        if any(folder in path.parents for folder in folders):
            item.add_marker(pytest.mark.numerics)
