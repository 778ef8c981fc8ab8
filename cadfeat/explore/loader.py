"""The explorer's set-up in the background: the server answers at once, the page shows the set-up's progress.

``SessionLoader(study)`` reads the study file (a bad one fails at once, before anything is served) and ``start()``
sets the ``ExploreSession`` up in a thread (``cadfeat.study.setup_cache.cached_setup``: the CAD builds and the
design map, or the set-up read from the set-up cache); ``SetupStatus`` is its progress (``GET /api/status``) and
``session()`` the session once it is ready (``NotReady`` before). A light module (the standard library; the
study layer is imported when used): the server and this loader are up before numpy and the measures are imported.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import TYPE_CHECKING

from cadfeat.errors import CadfeatError
from cadfeat.explore.status import NotReady, SetupStatus

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.explore.session import ExploreSession

__all__ = ["NotReady", "SessionLoader", "SetupStatus"]


class SessionLoader:
    """An ``ExploreSession`` set up in a background thread (``start``), so that the server can answer at once:
    ``status`` is the set-up's progress, ``session()`` the session once it is ready (``NotReady`` before, or
    after a failed set-up). The study file is read here, before the thread: a bad study fails at once."""

    def __init__(self, study: str | Path, results: str | Path | None = None, *, cache: bool | None = None) -> None:
        from cadfeat.study.schema import load_study  # (pydantic: the one import before the page is served)

        self.study, self.results, self.cache = study, results, cache
        self.status = SetupStatus(str(study))
        self.config = load_study(Path(study).resolve())
        self.status.study = self.config.study.name
        self._session: ExploreSession | None = None
        self.done = threading.Event()
        self._thread: threading.Thread | None = None

    @classmethod
    def of(cls, session: ExploreSession) -> SessionLoader:
        """A loader of a session that is set up already."""
        loader = cls.__new__(cls)
        loader.study, loader.results, loader.cache = session.study_path, None, None
        loader.status, loader.config, loader._session = session.status, session.config, session
        loader.status.finish()
        loader.done = threading.Event()
        loader.done.set()
        loader._thread = None
        return loader

    def start(self) -> SessionLoader:
        self._thread = threading.Thread(target=self._load, name="cadfeat-explore-setup", daemon=True)
        self._thread.start()
        return self

    def _load(self) -> None:
        try:
            from cadfeat.explore.session import ExploreSession  # (numpy, the measures: in this thread)

            self._session = ExploreSession(self.study, self.results, cache=self.cache, status=self.status,
                                           config=self.config)
            self.status.finish()
        except Exception as exc:  # noqa: BLE001 - shown on the page and printed by the command
            self.status.finish(str(exc) if isinstance(exc, CadfeatError) else f"{type(exc).__name__}: {exc}")
        finally:
            self.done.set()

    def session(self) -> ExploreSession:
        """The ``ExploreSession``; ``NotReady`` while it is being set up or after its set-up failed."""
        if self._session is None:
            raise NotReady(self.status)
        return self._session
