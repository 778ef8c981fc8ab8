"""The interactive explorer (``cadfeat explore STUDY``): the thesis GUI's successor (§5.4).

Sliders for the design variables; the part in 3-D with the camera path and frusta; per-hole and per-pose
measures and the objectives along the trajectory (thesis Figs. 5.9–5.11); the synthetic camera view at a pose
with the predicted rim ellipses; current vs optimum; write the design as a study start, or export STEP + GLB.

- ``session``: ``ExploreSession`` — the study loaded once; each slider move is scored by the study's own code
  on the feature model (no CAD rebuild);
- ``raycache``: exact per-ray cache of the occlusion test (only moved holes' rays are traced again);
- ``server``: the local HTTP server (standard library, 127.0.0.1) and the page in ``static/`` (three.js from
  ``cadfeat/report/vendor``).
"""

from __future__ import annotations

from cadfeat.explore.server import ExploreServer, serve
from cadfeat.explore.session import ExploreSession

__all__ = ["ExploreServer", "ExploreSession", "serve"]
