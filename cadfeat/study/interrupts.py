"""Ctrl-C during ``cadfeat run`` (issue 32 item 8): keep the best design so far, write it, exit 130.

A run passes through three stages, and SIGINT means something different in each (``RunInterrupts``, installed for
the whole run by ``run_study`` in the main thread, when SIGINT still has Python's default handler):

- **before any design** (the set-up): there is nothing to keep — Ctrl-C stops at once, nothing is written (status
  130), as without the handler;
- **in the optimiser** (``keeping()``: the optimisers, the outline rounds, the robust solve): Ctrl-C raises
  ``KeyboardInterrupt`` at once; the optimiser catches it and returns the best design it has evaluated
  (``interrupted``);
- **after the optimiser** (the robust phase's choice, the shop rounding, the CAD rebuild, the analysis, the export,
  the closed loop, the report): the first Ctrl-C is noted (``requested``) and the run finishes with the design it
  has — the rebuild, the requirement checks, the STEP/STL files, results.json and the report —, skipping what is
  left of the optional work (the robust phase, the shop's refinement on the rebuild, the robustness statistics,
  added targets, the closed-loop check, the camera views). The optimisers' progress callbacks raise once an
  interrupt is requested (``check``), so a solve that starts after it stops at its first evaluation.

A second Ctrl-C, at any stage, stops at once: ``KeyboardInterrupt`` unwinds, the staging folder is removed and
nothing is written. What a run writes is staged and published whole (``output_folder.staged_output``), so an
interrupted run leaves either its complete output folder — results.json marked ``"interrupted": true`` — or none.
``cadfeat run`` then exits 130 with ``cadfeat: interrupted``, naming the folder.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Generator
from types import FrameType

__all__ = ["RunInterrupts"]

KEEPING = ("cadfeat: interrupted: the optimiser stops; the best design so far is rebuilt, exported and reported "
           "(Ctrl-C again: stop at once, writing nothing)")
FINISHING = ("cadfeat: interrupted: finishing with the design found (rebuild, export, report; the optional analysis "
             "and the closed loop skipped; Ctrl-C again: stop at once, writing nothing)")


class RunInterrupts:
    """The run's SIGINT handling (module docstring). ``count``: the interrupts received; ``requested``: at least
    one (the run then takes the short way to its outputs)."""

    def __init__(self) -> None:
        self.count = 0
        self._stage = "abort"  # abort (no design yet) | keep (in an optimiser) | finish (after the optimiser) |
        # skip (an optional part after the optimiser)
        self._installed = False

    @property
    def requested(self) -> bool:
        return self.count > 0

    def _on_sigint(self, signum: int, frame: FrameType | None) -> None:
        self.count += 1
        if self.count > 1 or self._stage == "abort":
            raise KeyboardInterrupt
        print(f"\n{KEEPING if self._stage == 'keep' else FINISHING}", file=sys.stderr, flush=True)
        if self._stage in ("keep", "skip"):
            raise KeyboardInterrupt

    @contextlib.contextmanager
    def installed(self) -> Generator[RunInterrupts]:
        """Handle SIGINT as the module docstring says within the block (the main thread only, and only if SIGINT
        has Python's default handler: a caller with its own, e.g. a campaign, keeps it). The block starts in the
        "abort" stage; ``designing()`` moves it on."""
        main = threading.current_thread() is threading.main_thread()
        if not main or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
            yield self
            return
        previous = signal.signal(signal.SIGINT, self._on_sigint)
        self._installed = True
        try:
            yield self
        finally:
            signal.signal(signal.SIGINT, previous)
            self._installed = False

    def designing(self) -> None:
        """The optimiser is about to run: from now on there is a design to keep (the "finish" stage)."""
        self._stage = "finish"

    @contextlib.contextmanager
    def keeping(self) -> Generator[None]:
        """Within the block (an optimiser that returns its best design when ``KeyboardInterrupt`` reaches it), the
        first Ctrl-C raises at once; if one was requested already, ``KeyboardInterrupt`` is raised on entry."""
        with self._in("keep"):
            yield

    @contextlib.contextmanager
    def skippable(self) -> Generator[None]:
        """An optional part of the run after the optimiser (the robustness statistics, the closed-loop check):
        within the block the first Ctrl-C raises ``KeyboardInterrupt`` at once, and the caller goes on without
        the block's result; if one was requested already, it is raised on entry (the block is skipped)."""
        with self._in("skip"):
            yield

    @contextlib.contextmanager
    def _in(self, stage: str) -> Generator[None]:
        self.check()
        previous, self._stage = self._stage, stage if self._stage != "abort" or stage != "skip" else "abort"
        try:
            yield
        finally:
            self._stage = previous

    def check(self) -> None:
        """``KeyboardInterrupt`` if an interrupt was requested (the optimisers' progress callbacks call it)."""
        if self.requested:
            raise KeyboardInterrupt
