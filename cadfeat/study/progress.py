"""Terminal progress of a study (rich): one line per phase with its time, and the optimiser's iterations.

``StudyProgress`` also records the wall time of every phase (``timings_s`` of results.json) and the best
design the optimiser reported so far (kept if the run is interrupted with Ctrl-C), and carries the run's Ctrl-C
handling (``interrupts``: ``study.interrupts.RunInterrupts``).
"""

from __future__ import annotations

import contextlib
import numbers
import time
from collections.abc import Generator, Mapping
from typing import TYPE_CHECKING, cast

import numpy as np

from cadfeat.study.interrupts import RunInterrupts

if TYPE_CHECKING:  # pragma: no cover
    from types import TracebackType

    from rich.progress import Progress, TaskID

    from cadfeat.results import JsonDict

__all__ = ["StudyProgress"]


class StudyProgress:
    """Phases and optimiser iterations on the terminal (nothing if ``enabled`` is false)."""

    def __init__(self, title: str, enabled: bool = True, interrupts: RunInterrupts | None = None) -> None:
        self.title = title
        self.enabled = enabled
        self.interrupts = interrupts if interrupts is not None else RunInterrupts()
        """The run's Ctrl-C handling (``study.interrupts``): the phases ask it whether the run was interrupted."""
        self.timings: dict[str, float] = {}
        self.best_x: np.ndarray | None = None
        self.best_f = np.inf
        self.iterations = 0
        self._progress: Progress | None = None
        self._tasks: list[TaskID | None] = []
        self._t0 = time.perf_counter()

    def __enter__(self) -> StudyProgress:
        if self.enabled:
            from rich.console import Console
            from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

            self._progress = Progress(SpinnerColumn(), TextColumn("[bold]{task.description}"), BarColumn(),
                                      TextColumn("{task.fields[info]}"), TimeElapsedColumn(),
                                      console=Console(stderr=True), transient=False)
            self._progress.__enter__()
            self._progress.console.print(f"[bold]cadfeat[/bold] study {self.title}")
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.timings["total"] = time.perf_counter() - self._t0
        if self._progress is not None:
            self._progress.__exit__(exc_type, exc, tb)

    def log(self, text: str) -> None:
        if self._progress is not None:
            self._progress.console.print(text)

    @contextlib.contextmanager
    def phase(self, name: str, total: float | None = None) -> Generator[None]:
        """Time a phase (accumulated under ``name``) and show it while it runs."""
        t0 = time.perf_counter()
        task = self._progress.add_task(name, total=total, info="") if self._progress is not None else None
        self._tasks.append(task)
        try:
            yield
        finally:
            self._tasks.pop()
            dt = time.perf_counter() - t0
            self.timings[name] = self.timings.get(name, 0.0) + dt
            if task is not None and self._progress is not None:
                self._progress.update(task, completed=total if total is not None else 1, total=total or 1,
                                      info=f"{dt:.2f} s")

    def iteration(self, *args: object, **kwargs: object) -> None:
        """Optimiser callback: accepts a dict (``iteration``, ``f``, ``x``, ...), keyword arguments, or
        positional ``(x, f)``; keeps the best design seen."""
        info: JsonDict = {}
        for a in args:
            if isinstance(a, Mapping):
                info.update(cast("Mapping[str, object]", a))
        info.update(kwargs)
        if not info and len(args) >= 2:
            info = {"x": args[0], "f": args[1]}
        self.iterations += 1
        self._keep_best(info)
        self.interrupts.check()  # an interrupt requested after the optimiser: a solve started now stops here

    def _keep_best(self, info: Mapping[str, object]) -> None:
        value = info.get("f", info.get("f_best"))
        f = float(value) if isinstance(value, numbers.Real) else None  # (a Python or numpy number)
        x = info.get("x", info.get("x_best"))
        feasible = info.get("feasible", True)
        if f is not None and x is not None and bool(feasible) and np.isfinite(f) and f < self.best_f:
            self.best_f, self.best_x = f, np.array(x, dtype=float)
        if self._progress is not None and self._tasks and self._tasks[-1] is not None:
            best = f"best {self.best_f:.6g}" if np.isfinite(self.best_f) else ""
            phase = info.get("phase", "")
            self._progress.update(self._tasks[-1], info=f"iter {self.iterations} {phase} {best}".strip())
