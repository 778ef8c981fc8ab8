"""EDCircles (OpenCV contrib ``cv2.ximgproc.EdgeDrawing``) as the independent hole detector.

Written elsewhere (Akinlar & Topal 2013; the ED edge segments, arcs joined into circles and ellipses, each
validated by the a-contrario Number of False Alarms), it knows nothing of cadfeat's rims, renderer or prior:
the referee that is not the defendant (docs/design.md "Closed loop"). It finds every ellipse in the image — with a
chamfer both the bore's and the chamfer's edges; association by prediction (``detection.associate``) then keeps
the one nearest each predicted rim centre, which is how a practitioner would use it.

Output layout of ``EdgeDrawing.detectEllipses`` (opencv-contrib 5.0, verified against ellipses drawn with
``cv2.ellipse`` at 1/16 px and area-averaged, tests/vision/test_detectors.py): an (M, 1, 6) float64 array of
rows (cx, cy, r, a, b, angle_deg). A circle has r > 0 (its radius) and a = b = 0; an ellipse has r = 0, a and
b its **semi**-axes, and angle_deg the angle in **degrees** of the a axis from +u towards +v (``cv2.ellipse``'s
convention; a is not necessarily the major one). Pixel centres are at integer coordinates. ``to_detections``
converts to cadfeat's ``Detections`` (full axes major ≥ minor, angle rad of the major axis wrapped to
[−π/2, π/2)); ``residual_px`` is NaN (EDCircles reports none).

Lens distortion: EDCircles returns the fitted ellipse only, not its edge points, so the centre is the ellipse
fitted to the distorted rim, kept as found (off by the second-order term of ``detection.undistorted_centre``:
0.1–0.3 px for the thesis's strong lens and 8 px rims). ``camera`` is accepted for the common signature and
not used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import Camera
from cadfeat.vision.detection import Detections, _empty


@dataclass(frozen=True)
class EDCirclesSettings:
    """``EdgeDrawing.Params`` used (OpenCV's defaults except where noted): ``operator`` 0 Prewitt, 1 Sobel,
    2 Scharr; ``gradient_threshold`` (grey levels of the operator's response, default 20; a weaker edge is not
    an edge); ``anchor_threshold``; ``min_path_length`` px (default 10); ``sigma`` the pre-smoothing Gaussian
    (default 1.0); ``pf_mode`` EDPF's parameter-free edges (default off); ``nfa_validation`` a-contrario
    validation (default on). ``min_minor_px`` drops smaller ellipses (not an EDCircles parameter)."""

    operator: int = 0
    gradient_threshold: int = 20
    anchor_threshold: int = 0
    min_path_length: int = 10
    sigma: float = 1.0
    pf_mode: bool = False
    nfa_validation: bool = True
    min_minor_px: float = 2.5


def _edge_drawing(cfg: EDCirclesSettings):  # noqa: ANN202 — cv2's own type
    import cv2

    ed = cv2.ximgproc.createEdgeDrawing()
    p = cv2.ximgproc.EdgeDrawing.Params()
    p.EdgeDetectionOperator = cfg.operator
    p.GradientThresholdValue = cfg.gradient_threshold
    p.AnchorThresholdValue = cfg.anchor_threshold
    p.MinPathLength = cfg.min_path_length
    p.Sigma = cfg.sigma
    p.PFmode = cfg.pf_mode
    p.NFAValidation = cfg.nfa_validation
    ed.setParams(p)
    return ed


def to_detections(rows: np.ndarray | None, min_minor_px: float = 0.0) -> Detections:
    """``detectEllipses`` rows (M, 6) or (M, 1, 6) (module docstring) → ``Detections`` (NaN residuals)."""
    if rows is None or np.size(rows) == 0:
        return _empty()
    r = np.asarray(rows, float).reshape(-1, 6)
    circle = r[:, 2] > 0
    a = np.where(circle, r[:, 2], r[:, 3])
    b = np.where(circle, r[:, 2], r[:, 4])
    angle = np.radians(np.where(circle, 0.0, r[:, 5])) + np.where(a >= b, 0.0, np.pi / 2)
    axes = 2 * np.stack([np.maximum(a, b), np.minimum(a, b)], axis=-1)
    keep = axes[:, 1] >= min_minor_px
    angle = (angle + np.pi / 2) % np.pi - np.pi / 2
    return Detections(r[keep, :2], axes[keep], angle[keep], np.full(int(keep.sum()), np.nan))


def detect_edcircles(image: np.ndarray, *, camera: Camera | None = None, origin_px: ArrayLike = (0.0, 0.0),
                     settings: EDCirclesSettings | None = None) -> Detections:
    """All circles and ellipses EDCircles finds in a grey uint8 image (H, W), in the image's own pixels
    (module docstring). ``camera`` and ``origin_px`` are accepted for the common signature and not used."""
    import cv2

    del camera, origin_px
    cfg = settings or EDCirclesSettings()
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    img = np.ascontiguousarray(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    ed = _edge_drawing(cfg)
    ed.detectEdges(img)
    return to_detections(ed.detectEllipses(), cfg.min_minor_px)
