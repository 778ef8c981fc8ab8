"""Hole detection on recorded images, without a study: what ``cadfeat detect IMAGES…`` runs.

A practitioner's first question of a recording — does the detector see my holes in *these* images? — needs no CAD
model, poses or study: each image file is read (``image_files.read_grey``), given to each chosen detector of
``detectors.DETECTORS`` without a prior, and every ellipse found is reported. Without a prior the ``"cadfeat"``
detector is ``detection.detect_holes`` (threshold + contours + sub-pixel edge + ``cv2.fitEllipse``, its residual
and surround tests), as in the closed loop before a pose is known; ``"edcircles"`` and ``"blob"`` are the same
calls as in the closed loop.

Polarity (``holes``): the detectors look for holes **darker** than the face around them (a lit part, dark bores).
With ``holes="bright"`` — a backlit part, or white dots on a dark target — the grey image is inverted
(255 − grey) first, so that every detector sees dark ellipses on a bright face.

Lens: with a ``camera`` (a calibration file) the ``"cadfeat"`` detector's centres are those of the undistorted rim
(``detection.undistorted_centre``, in distorted-image pixels: the quantity the closed loop predicts); the others
keep their fit in the distorted image. An image whose size is not the calibration's is not detected: reported.

Coordinates: pixels of the image as stored, origin at the top-left pixel's centre, u to the right, v down (OpenCV's
convention); axes are full lengths (major ≥ minor) in px, the angle that of the major axis from +u towards +v in
degrees (−90, 90]. A file that is missing or not an image is reported by name (``ImageResult.problem``); the
others go on.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypedDict

import numpy as np

from cadfeat.camera import Camera
from cadfeat.vision.detection import Detections
from cadfeat.vision.detectors import DETECTORS, detect
from cadfeat.vision.image_files import ImageFileError, read_grey

#: Hole polarities: darker or brighter than the face around them.
HOLE_POLARITIES = ("dark", "bright")
#: Columns of the detections CSV (``csv_rows``); units in the names (px, deg).
CSV_COLUMNS = ("image", "detector", "index", "u_px", "v_px", "major_px", "minor_px", "angle_deg", "residual_px")


@dataclass(frozen=True)
class ImageResult:
    """One image's outcome: ``path``; ``size_px`` (width, height) when read; ``found`` the ``Detections`` per
    detector name (empty when not detected); ``problem`` why the image was not detected (None when it was)."""

    path: Path
    size_px: tuple[int, int] | None = None
    found: dict[str, Detections] = field(default_factory=dict[str, Detections])
    problem: str | None = None

    @property
    def counts(self) -> dict[str, int]:
        """Ellipses found per detector."""
        return {name: len(d) for name, d in self.found.items()}


def _check_choices(detectors: Sequence[str], holes: str) -> None:
    unknown = [d for d in detectors if d not in DETECTORS]
    if unknown or not detectors:
        raise ValueError(f"detectors {list(detectors)!r}: allowed: one or more of {DETECTORS}")
    if holes not in HOLE_POLARITIES:
        raise ValueError(f"holes {holes!r}: allowed: one of {HOLE_POLARITIES}")


def detect_grey(grey: np.ndarray, detectors: Sequence[str], holes: str = "dark",
                camera: Camera | None = None) -> dict[str, Detections]:
    """Ellipses found in a grey uint8 image (H, W) by each of ``detectors`` (module docstring: ``holes`` polarity,
    ``camera`` for the lens), in the image's pixels."""
    _check_choices(detectors, holes)
    image = 255 - np.asarray(grey, np.uint8) if holes == "bright" else np.asarray(grey, np.uint8)
    return {name: detect(name, image, camera=camera) for name in detectors}


def detect_file(path: str | Path, detectors: Sequence[str], holes: str = "dark",
                camera: Camera | None = None) -> ImageResult:
    """``detect_grey`` on the image file ``path``; a missing or unreadable file, or one of another size than
    ``camera``'s, gives an ``ImageResult`` with its ``problem`` (never raises for the file)."""
    path = Path(path)
    try:
        grey = read_grey(path)
    except ImageFileError as exc:
        return ImageResult(path, problem=exc.reason)
    h, w = grey.shape
    if camera is not None and (w, h) != (camera.width, camera.height):
        return ImageResult(path, (w, h), problem=f"the image is {w}x{h} px, the calibration's camera "
                                                 f"{camera.width}x{camera.height} px: not detected")
    return ImageResult(path, (w, h), detect_grey(grey, detectors, holes, camera))


def detect_files(paths: Sequence[str | Path], detectors: Sequence[str], holes: str = "dark",
                 camera: Camera | None = None,
                 progress: Callable[[int, int, ImageResult], None] | None = None) -> list[ImageResult]:
    """``detect_file`` on each of ``paths`` in order; ``progress(i, n, result)`` after each (i from 1)."""
    _check_choices(detectors, holes)
    results = []
    for i, path in enumerate(paths, start=1):
        result = detect_file(path, detectors, holes, camera)
        results.append(result)
        if progress is not None:
            progress(i, len(paths), result)
    return results


def ellipse_rows(found: Detections) -> list[dict[str, float | None]]:
    """The ellipses of one detector's ``Detections`` as plain rows: ``u_px``, ``v_px``, ``major_px``,
    ``minor_px``, ``angle_deg`` (major axis from +u towards +v, (−90, 90]) and ``residual_px`` (the fit's largest
    boundary deviation; None where the detector reports none)."""
    rows = []
    for c, ax, ang, res in zip(found.centre_px, found.axes_px, found.angle_rad, found.residual_px, strict=True):
        deg = float(np.degrees(ang))
        rows.append({"u_px": float(c[0]), "v_px": float(c[1]), "major_px": float(ax[0]), "minor_px": float(ax[1]),
                     "angle_deg": deg + 180.0 if deg <= -90.0 else deg,
                     "residual_px": float(res) if np.isfinite(res) else None})
    return rows


class PerImage(TypedDict):
    """The fewest, median and most ellipses a detector found per detected image."""

    min: int
    median: float
    max: int


class DetectorSummary(TypedDict):
    """One detector's counts over the run (``summary``)."""

    ellipses: int
    images_with_ellipses: int
    per_image: PerImage | None


class NotDetected(TypedDict):
    """An image that could not be detected: its path as given and the problem (one line)."""

    image: str
    problem: str | None


class Summary(TypedDict):
    """``summary``: images given and detected, per detector its counts, the images not detected."""

    images: int
    images_detected: int
    detectors: dict[str, DetectorSummary]
    not_detected: list[NotDetected]


def csv_rows(results: Sequence[ImageResult]) -> list[dict[str, str | int | float | None]]:
    """One row per ellipse found (``CSV_COLUMNS``): the image's path as given, the detector, the ellipse's index
    in that image (from 0) and ``ellipse_rows``'s numbers."""
    return [{"image": str(r.path), "detector": name, "index": k, **row}
            for r in results for name, found in r.found.items() for k, row in enumerate(ellipse_rows(found))]


def summary(results: Sequence[ImageResult], detectors: Sequence[str]) -> Summary:
    """Per detector: images detected, images with at least one ellipse, ellipses found in all, and the fewest,
    median and most per detected image; plus the images not detected (path and problem)."""
    done = [r for r in results if r.problem is None]
    out: Summary = {"images": len(results), "images_detected": len(done), "detectors": {},
                    "not_detected": [{"image": str(r.path), "problem": r.problem}
                                     for r in results if r.problem is not None]}
    for name in detectors:
        n = np.array([r.counts.get(name, 0) for r in done], int)
        per: PerImage | None = ({"min": int(n.min()), "median": float(np.median(n)), "max": int(n.max())}
                                if len(n) else None)
        out["detectors"][name] = {"ellipses": int(n.sum()), "images_with_ellipses": int(np.sum(n > 0)),
                                  "per_image": per}
    return out


def to_json(results: Sequence[ImageResult], detectors: Sequence[str], holes: str,
            calibration: str | None = None) -> dict[str, object]:
    """The whole run as plain data: the settings, ``summary`` and per image its size, counts and ellipses."""
    return {
        "settings": {"detectors": list(detectors), "holes": holes, "calibration": calibration,
                     "units": "px (origin at the top-left pixel's centre, u right, v down); angle_deg: the major "
                              "axis from +u towards +v"},
        "summary": summary(results, detectors),
        "images": [{"image": str(r.path), "width_px": r.size_px[0] if r.size_px else None,
                    "height_px": r.size_px[1] if r.size_px else None, "problem": r.problem, "counts": r.counts,
                    "ellipses": {name: ellipse_rows(found) for name, found in r.found.items()}}
                   for r in results],
    }


#: Drawing colours (B, G, R) per detector in ``annotated`` pictures.
COLOURS_BGR = {"cadfeat": (40, 40, 230), "edcircles": (60, 200, 40), "blob": (230, 120, 20)}
_SHIFT = 4  # cv2 drawing with 4 fractional bits: ellipses placed to 1/16 px


def annotated(grey: np.ndarray, found: dict[str, Detections]) -> np.ndarray:
    """BGR uint8 copy of a grey image (H, W) with each detector's ellipses (``COLOURS_BGR``: cadfeat red,
    EDCircles green, blob blue), a cross at each centre, the ellipse's index (as in the CSV) to its right (one line
    per detector), and a legend of the counts at the top left."""
    import cv2

    out = cv2.cvtColor(np.asarray(grey, np.uint8), cv2.COLOR_GRAY2BGR)
    s = 1 << _SHIFT
    for j, (name, d) in enumerate(found.items()):
        colour = COLOURS_BGR.get(name, (0, 200, 230))
        for k, (c, ax, ang) in enumerate(zip(d.centre_px, d.axes_px, d.angle_rad, strict=True)):
            if not (np.all(np.isfinite(c)) and np.all(np.isfinite(ax))):
                continue
            centre = (round(c[0] * s), round(c[1] * s))
            half = (max(round(ax[0] / 2 * s), 1), max(round(ax[1] / 2 * s), 1))
            cv2.ellipse(out, centre, half, float(np.degrees(ang)), 0, 360, colour, 1, cv2.LINE_AA, _SHIFT)
            cv2.drawMarker(out, (round(c[0]), round(c[1])), colour, cv2.MARKER_CROSS, 7, 1)
            label = (round(c[0] + ax[1] / 2 + 2), round(c[1] - 2 + 10 * j))
            cv2.putText(out, str(k), label, cv2.FONT_HERSHEY_PLAIN, 0.8, colour, 1, cv2.LINE_AA)
    for row, (name, d) in enumerate(found.items()):
        cv2.putText(out, f"{name}: {len(d)}", (5, 14 + 14 * row), cv2.FONT_HERSHEY_PLAIN, 1.0,
                    COLOURS_BGR.get(name, (0, 200, 230)), 1, cv2.LINE_AA)
    return out
