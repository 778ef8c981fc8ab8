"""``cv2.SimpleBlobDetector`` as the naive practitioner's hole detector.

Settings a practitioner would pick for dark holes in a lit part: dark blobs (``blobColor`` 0), circularity
filter on with a modest minimum (0.5: oblique holes are ellipses), OpenCV's defaults otherwise (thresholds
10–220 in steps of 10, ``minRepeatability`` 2, area 25–5000 px², inertia ≥ 0.1, convexity ≥ 0.95). The
default area ceiling matters: with a larger one, at thresholds above the face's grey the whole image region
becomes one "dark blob" whose centroid is merged with a hole's near the image centre (measured: 0.5–1.2 px
off on a uniform synthetic face).

What it reports: each keypoint's ``pt`` is the mean of the centroids (image moments) of the blob's
thresholded **regions** over the threshold steps, and ``size`` its mean diameter — a region centroid, with no
shape model and no edge. For a whole dark ellipse on a uniform face that is the ellipse's centre (up to the
thresholds' pixel quantisation); for a lit crescent, a bright floor or a chamfer band it is the centroid of
whatever dark region the thresholds cut out, not the rim's centre. ``Detections`` gives a circle: axes
(size, size), angle 0, residual NaN. Lens distortion is not corrected (no edge points): ``camera`` is accepted
for the common signature and not used.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from cadfeat.camera import Camera
from cadfeat.vision.detection import Detections, _empty

#: Minimum circularity 4πA/P² kept (OpenCV's default is 0.8).
MIN_CIRCULARITY = 0.5


def blob_params():  # noqa: ANN201 — cv2's own type
    """The ``cv2.SimpleBlobDetector_Params`` of the module docstring."""
    import cv2

    p = cv2.SimpleBlobDetector_Params()
    p.filterByColor = True
    p.blobColor = 0
    p.filterByCircularity = True
    p.minCircularity = MIN_CIRCULARITY
    return p


def detect_blobs(image: np.ndarray, *, camera: Camera | None = None,
                 origin_px: ArrayLike = (0.0, 0.0)) -> Detections:
    """Dark blobs of a grey uint8 image (H, W) as circles (module docstring), in the image's own pixels."""
    import cv2

    del camera, origin_px
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    img = np.ascontiguousarray(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    kps = cv2.SimpleBlobDetector_create(blob_params()).detect(img)
    if not kps:
        return _empty()
    centre = np.array([k.pt for k in kps], float)
    size = np.array([k.size for k in kps], float)
    return Detections(centre, np.stack([size, size], axis=-1), np.zeros(len(kps)), np.full(len(kps), np.nan))
