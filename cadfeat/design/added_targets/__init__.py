"""Added target holes as design variables (issue 31): candidate sites on the allowed faces that keep every
requirement (``sites``), g_POSE of the part's holes plus added ones batched over designs (``objective``), the
lazy-greedy choice and its exhaustive reference (``greedy``), and the continuous refinement (``refine``).
The study phase is ``cadfeat.study.added_targets``; the CAD side ``cadfeat.cad.drill_targets``."""

from cadfeat.design.added_targets.greedy import GreedyResult, exhaustive, lazy_greedy
from cadfeat.design.added_targets.objective import PoseScene, TargetObjective
from cadfeat.design.added_targets.refine import Movable, Refined, refine
from cadfeat.design.added_targets.sites import (
    FaceRules,
    Sites,
    conflicts,
    face_grid,
    keepin_margin,
    site_margins,
    sites_on_faces,
)

__all__ = ["FaceRules", "GreedyResult", "Movable", "PoseScene", "Refined", "Sites", "TargetObjective", "conflicts",
           "exhaustive", "face_grid", "keepin_margin", "lazy_greedy", "refine", "site_margins", "sites_on_faces"]
