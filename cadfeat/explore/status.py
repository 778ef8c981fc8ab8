"""The explorer's set-up progress (``SetupStatus``: what ``GET /api/status`` answers and the page shows while the
study is set up) and ``NotReady`` (a request that needs the study before then: HTTP 503). Standard library only."""

from __future__ import annotations

import threading
import time
from typing import Any

from cadfeat.errors import CadfeatError

__all__ = ["NotReady", "SetupStatus"]


class SetupStatus:
    """The explorer's set-up as the page shows it while it runs (``GET /api/status``): ``state`` "setting-up",
    "ready" or "failed", the current ``phase``, the seconds since the explorer started, whether the set-up came
    from the cache, and the error of a failed set-up. Thread-safe."""

    def __init__(self, study: str = "") -> None:
        self._lock = threading.Lock()
        self.t0 = time.perf_counter()
        self.study = study
        self.state = "setting-up"
        self.phase = "reading the study"
        self.cache = "off"
        self.saved_s: float | None = None
        self.error: str | None = None
        self.ready_s: float | None = None

    def set_phase(self, phase: str) -> None:
        with self._lock:
            self.phase = phase

    def finish(self, error: str | None = None) -> None:
        with self._lock:
            self.state, self.error = ("failed", error) if error is not None else ("ready", None)
            self.phase = "failed" if error is not None else "ready"
            self.ready_s = time.perf_counter() - self.t0

    def to_dict(self) -> dict[str, Any]:
        with self._lock:
            return {"state": self.state, "phase": self.phase, "study": self.study,
                    "elapsed_s": round(time.perf_counter() - self.t0, 2), "cache": self.cache,
                    "cache_saved_s": None if self.saved_s is None else round(self.saved_s, 1),
                    "ready_s": None if self.ready_s is None else round(self.ready_s, 2), "error": self.error}


class NotReady(CadfeatError):
    """A request the explorer cannot answer before its set-up is done (HTTP 503, with the set-up's status)."""

    def __init__(self, status: SetupStatus) -> None:
        super().__init__(f"the study is still being set up ({status.phase})" if status.state == "setting-up"
                         else f"the study's set-up failed: {status.error}")
        self.status = status
