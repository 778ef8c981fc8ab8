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
