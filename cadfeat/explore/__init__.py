"""The interactive explorer (``cadfeat explore STUDY``): the thesis GUI's successor (§5.4).

Sliders for the design variables; the part in 3-D with the camera path and frusta; per-hole and per-pose
measures and the objectives along the trajectory (thesis Figs. 5.9–5.11); the synthetic camera view at a pose
with the predicted rim ellipses; current vs optimum; write the design as a study start, or export STEP + GLB.

- ``session``: ``ExploreSession`` — the study loaded once (read from the set-up cache when its inputs were set up
  before); each slider move is scored by the study's own code on the feature model (no CAD rebuild);
- ``loader``: ``SessionLoader`` sets the session up in a background thread while the server already answers
  (``status.SetupStatus``: the set-up's progress, which the page shows);
- ``raycache``: exact per-ray cache of the occlusion test (only moved holes' rays are traced again);
- ``server``: the local HTTP server (standard library, 127.0.0.1) and the page in ``static/`` (three.js from
  ``cadfeat/report/vendor``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.explore.loader import SessionLoader
    from cadfeat.explore.server import ExploreServer, serve
    from cadfeat.explore.session import ExploreSession
    from cadfeat.explore.status import SetupStatus

__all__ = ["ExploreServer", "ExploreSession", "SessionLoader", "SetupStatus", "serve"]
_HOMES = {"ExploreServer": "server", "serve": "server", "ExploreSession": "session", "SessionLoader": "loader",
          "SetupStatus": "status"}


def __getattr__(name: str) -> object:
    """The public names, imported on first use (the server starts before numpy and the measures are imported)."""
    if name in _HOMES:
        return getattr(importlib.import_module(f"cadfeat.explore.{_HOMES[name]}"), name)
    raise AttributeError(f"module 'cadfeat.explore' has no attribute {name!r}")
