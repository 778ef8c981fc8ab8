"""What the report needs besides results.json: the shapes, holes, camera and trajectory of the study."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.poses import cam_from_part
from cadfeat.results import Measures, Results, present, section

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape, Workplane

    from cadfeat.cad.features import Hole
    from cadfeat.camera import Camera
    from cadfeat.trajectory import Trajectory


@dataclass
class ReportContext:
    """Live objects of a study that the renders need (results.json holds only plain data).

    ``shape_before``/``shape_after`` are CadQuery shapes (or Workplanes), ``holes_before``/``holes_after``
    lists of ``cadfeat.cad.features.Hole`` in the part frame (mm), ``fixed_mask`` one bool per hole (True = the
    study kept it fixed), ``camera`` a ``cadfeat.camera.Camera``, ``trajectory`` a
    ``cadfeat.trajectory.Trajectory`` of ``T_task_cam`` poses, ``T_task_part`` the (4, 4) part pose in the
    task frame (identity when None) and ``sample_indices`` the trajectory samples whose camera views are
    rendered (default: first, middle and last). Every field may be None: what cannot be drawn is skipped
    with a note in the report.
    """

    shape_before: Shape | Workplane | None = None
    shape_after: Shape | Workplane | None = None
    holes_before: Sequence[Hole] | None = None
    holes_after: Sequence[Hole] | None = None
    fixed_mask: Sequence[bool] | np.ndarray | None = None
    camera: Camera | None = None
    trajectory: Trajectory | None = None
    T_task_part: np.ndarray | None = None
    sample_indices: Sequence[int] | None = None

    def samples(self, default: Sequence[int] | None = None) -> list[int]:
        """Trajectory sample indices for the camera views: ``sample_indices`` (clipped, unique, sorted), else
        ``default`` (the report passes each hole's worst pose), else first/middle/last."""
        if self.trajectory is None:
            return []
        n = len(self.trajectory)
        if n == 0:
            return []
        chosen = self.sample_indices if self.sample_indices is not None else default if default else \
            (0, n // 2, n - 1)
        return sorted({min(max(int(i) + (n if int(i) < 0 else 0), 0), n - 1) for i in chosen})

    def T_cam_part(self, indices: Sequence[int]) -> np.ndarray:
        """(K, 4, 4) part-to-camera transforms at the given samples (``poses.cam_from_part``)."""

        T_task_part = np.eye(4) if self.T_task_part is None else np.asarray(self.T_task_part, dtype=float)
        T_task_cam = np.asarray(self.trajectory.T_task_cam, dtype=float)[list(indices)]
        return cam_from_part(T_task_cam, T_task_part)


#: Most camera views per design (one per distinct worst pose, in hole order).
MAX_VIEWS = 6


def worst_poses(results: Results) -> dict[int, list[str]]:
    """{trajectory sample: names of the holes whose worst pose it is} over the after (else before) design's
    per-feature ``worst_pose`` (``results.FeatureSummary``), at most ``MAX_VIEWS`` samples."""
    m = section(results, "measures", Measures)
    design = (m.after if present(m.after) else m.before) if m is not None else None
    out: dict[int, list[str]] = {}
    for i, f in enumerate(design.per_feature if design is not None else []):
        k = f.worst_pose
        if k is not None and (k in out or len(out) < MAX_VIEWS):
            out.setdefault(k, []).append(str(f.name or f"#{i}"))
    return out
