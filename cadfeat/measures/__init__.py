"""Per-pose, per-feature measures of the thesis (chapters 3–4), batched over L poses × N features.

Modules: ``fov`` (eq. 3.1–3.3 cone, rectangular sensor), ``focus`` (eq. 3.4–3.6), ``ellipse``
(exact rim conic, sphere conic eq. 3.13–3.18), ``resolution`` (§3.3.3, eq. 3.7, 3.22), ``jacobian``
(eq. 4.9–4.15, 4.20–4.21), ``resolvability`` (eq. 4.27–4.32), ``visibility`` (facing, occlusion),
``evaluate`` (everything at once), ``pose_information`` (Fisher information of the pose, CRLB, bias; docs/design.md
"Pose accuracy"; the filter's posterior CRLB is ``cadfeat.vision.posterior_crlb``) with ``pose_models``
(calibrated detection / measurement models), ``rim_centre`` (the measured point of a hole: its rim ellipse's
centre and that centre's 2×6 pose Jacobian) and ``rim_occlusion`` (hidden fraction of each rim). All margins:
positive = satisfied, finite (never NaN), strongly negative for features behind the camera. Frames: OpenCV camera
frame, mm, px.
"""

from __future__ import annotations

from cadfeat.measures.ellipse import Ellipse, hole_ellipse, sphere_ellipse
from cadfeat.measures.evaluate import Measures, evaluate
from cadfeat.measures.focus import focus_margin
from cadfeat.measures.fov import fov_cone_margin, fov_image_margin_px
from cadfeat.measures.jacobian import image_jacobian, jacobian_diagnostics, stacked_jacobian
from cadfeat.measures.pose_information import PoseInformation, pose_information
from cadfeat.measures.resolution import line_segment_margin_px, resolution_margin_px, resolution_margin_sphere
from cadfeat.measures.resolvability import resolvability
from cadfeat.measures.visibility import facing_margin, occluded

__all__ = [
    "Ellipse", "Measures", "evaluate", "facing_margin", "focus_margin", "fov_cone_margin", "fov_image_margin_px",
    "hole_ellipse", "image_jacobian", "jacobian_diagnostics", "line_segment_margin_px", "occluded",
    "PoseInformation", "pose_information",
    "resolution_margin_px", "resolution_margin_sphere", "resolvability", "sphere_ellipse", "stacked_jacobian",
]
