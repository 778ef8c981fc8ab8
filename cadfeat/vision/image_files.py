"""Camera images read from files as a real camera writes them: PNG, JPEG, TIFF, BMP or PGM/PPM (the netpbm
formats many machine-vision tools record in), 8 or 16 bit, colour or grey.

``read_grey`` gives the (H, W) uint8 grey image the detectors take; a 16-bit image is scaled to 8 bits by its
bit depth (÷ 257), a colour image is converted with OpenCV's luma weights. Every failure raises ``ImageFileError``
naming the file, so a command that reads many images can report it and go on.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cadfeat.errors import CadfeatError

#: File name endings read as images (lower case).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm", ".ppm", ".pnm")


class ImageFileError(CadfeatError):
    """An image file is missing, unreadable or of an unsupported kind; ``path`` names it."""

    def __init__(self, path: str | Path, reason: str) -> None:
        super().__init__(f"{path}: {reason}")
        self.path = Path(path)
        self.reason = reason


def read_grey(path: str | Path) -> np.ndarray:
    """The image at ``path`` as (H, W) uint8 grey levels (0-255); raises ``ImageFileError`` naming the file."""
    import cv2

    path = Path(path)
    if not path.is_file():
        raise ImageFileError(path, "image file not found")
    data = np.fromfile(str(path), dtype=np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if image is None:
        raise ImageFileError(path, f"not a readable image (allowed: {', '.join(IMAGE_SUFFIXES)}; 8 or 16 bit)")
    return to_grey8(image, path)


def to_grey8(image: np.ndarray, path: str | Path = "<image>") -> np.ndarray:
    """(H, W) uint8 grey of a decoded image: (H, W) or (H, W, 3|4) BGR(A), uint8, uint16 or float in [0, 1]."""
    import cv2

    if image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    if image.ndim == 3 and image.shape[2] in (3, 4):
        image = cv2.cvtColor(image, cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY)
    if image.ndim != 2:
        raise ImageFileError(path, f"unsupported image shape {image.shape} (allowed: grey, BGR or BGRA)")
    if image.dtype == np.uint8:
        return image
    if image.dtype == np.uint16:
        return np.round(image.astype(np.float32) / 257.0).astype(np.uint8)
    if np.issubdtype(image.dtype, np.floating):
        return np.clip(np.round(image.astype(np.float32) * 255.0), 0, 255).astype(np.uint8)
    raise ImageFileError(path, f"unsupported pixel type {image.dtype} (allowed: 8 or 16 bit, or float)")


def image_files(folder: str | Path) -> list[Path]:
    """The image files directly in ``folder`` (``IMAGE_SUFFIXES``), sorted by name."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CadfeatError(f"{folder}: not a folder of images")
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())


def expand_image_paths(items: Sequence[str | Path]) -> list[Path]:
    """The images named on a command line, in the order given: a folder stands for its image files
    (``image_files``, sorted by name); any other name is kept as it is, missing or not, so that the command
    reports it by name (``read_grey``) and goes on."""
    out: list[Path] = []
    for item in items:
        p = Path(item)
        out.extend(image_files(p) if p.is_dir() else [p])
    return out
