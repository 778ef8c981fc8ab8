"""Pre-flight checks of a study: refuse, before any optimisation, a study that cannot mean anything
(DESIGN.md, "Trust rules").

``check_visibility``: the camera must see at least one hole at one trajectory sample.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cadfeat.study.schema import StudyError

__all__ = ["check_visibility"]


def check_visibility(measures: Any, label: str) -> None:
    """Raise ``StudyError`` if no hole is seen at any trajectory sample.

    A hole is seen at a sample when ``measures.visible`` (in front of the camera, its face turned towards
    it) and its centre is inside the field of view (the cone margin ``fov`` ≥ 0, thesis eq. 3.1–3.3, or the
    rectangular sensor's margin ``fov_px`` ≥ 0). ``measures`` is a ``measures.Measures`` of the original
    design, arrays (L, N) (``facing`` > 0: the camera is on the outward side of the hole's face). The message
    names the likely cause: the holes face away from the camera at every sample (e.g. a camera below the part),
    or the camera never looks at the part (e.g. a trajectory centred far from it).
    """
    visible = np.asarray(measures.visible, bool)
    in_view = (np.asarray(measures.fov, float) >= 0.0) | (np.asarray(measures.fov_px, float) >= 0.0)
    if visible.size == 0 or (visible & in_view).any():
        return
    L, N = visible.shape
    if not (np.asarray(measures.facing, float) > 0.0).any():
        cause = "at every sample the camera is behind the holes' faces (e.g. a camera below the part)"
    else:
        cause = ("no hole is ever in front of the camera and inside its field of view: the trajectory does not look "
                 "at the part (e.g. its centre or target far from the part; check [trajectory] and [part_pose], "
                 "all in mm)")
    raise StudyError(f"{label}: the camera never sees the part: none of its {N} hole(s) is seen at any of the {L} "
                     f"trajectory samples; {cause}. Nothing was optimised.")
