"""The closed loop: synthetic image sequences, OpenCV hole detection and EKF/IEKF/PnP pose tracking.

Modules (one concept each, docs/design.md "Closed loop"): ``config`` (``TrackingConfig``: the study's
``[tracking]`` section, run in a cell), ``images`` (render along a trajectory, thin-lens
defocus, motion blur, grey-level noise, 8-bit quantisation), ``detection`` (threshold + contours +
``cv2.fitEllipse``; association by prediction with a gate), ``detectors`` (``detect(kind, ...)`` over
``DETECTORS``: ``edge_detector`` — cadfeat's rim edges around the predicted ellipses, for physically lit
images —, ``edcircles`` — OpenCV contrib's EDCircles — and ``blob`` — ``cv2.SimpleBlobDetector``),
``measurement`` (the rim ellipse-centre measurement and its analytic Jacobian), ``motion`` (12-state
constant-velocity model on SE(3), thesis eq. 6.1), ``estimate`` (``estimate_poses``: EKF, IEKF, solvePnP;
thesis §6.3.1–6.3.2), ``metrics`` (errors, Monte-Carlo intervals, paired test), ``closed_loop`` (one design,
before vs after).
OpenCV, SciPy and the renderer are imported where used.
"""

from __future__ import annotations

from cadfeat.measures.rim_centre import rim_centre_jacobian, rim_centre_px
from cadfeat.vision.crlb import posterior_crlb
from cadfeat.vision.estimate import METHODS, FilterTuning, Track, TrackingError, estimate_poses
from cadfeat.vision.images import SensorModel

__all__ = ["METHODS", "FilterTuning", "SensorModel", "Track", "TrackingError", "estimate_poses", "posterior_crlb",
           "rim_centre_jacobian", "rim_centre_px"]
