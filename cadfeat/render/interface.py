"""One interface for the closed loop's two renderers: the raster one (VTK) and the physically based one (Mitsuba).

``CameraRenderer`` is the protocol both satisfy: ``render(T_cam_part)`` (the renderer's own image: RGB uint8 for
the raster, linear radiance float32 for the PBR), ``render_grey(T_cam_part)`` (what the closed loop reads:
noiseless grey (H, W) float32 in 0 … 255), ``close()`` and the context manager. ``camera_renderer(kind, shape,
holes, camera, **cell)`` builds either; ``grey_sequence(renderer, T_cam_part)`` renders a trajectory's frames.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Literal, Protocol, runtime_checkable

import numpy as np

from cadfeat.cell.defaults import RENDERERS
from cadfeat.render.scene import RenderError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole, ShapeLike
    from cadfeat.camera import Camera

__all__ = ["RENDERER_KINDS", "CameraRenderer", "camera_renderer", "grey_sequence"]

RENDERER_KINDS = RENDERERS


@runtime_checkable
class CameraRenderer(Protocol):
    """A renderer of the study camera's images at poses ``T_cam_part`` (4, 4) (part → camera frame, mm)."""

    def render(self, T_cam_part: np.ndarray) -> np.ndarray: ...

    def render_grey(self, T_cam_part: np.ndarray) -> np.ndarray: ...

    def close(self) -> None: ...

    def __enter__(self) -> CameraRenderer: ...

    def __exit__(self, *exc: object) -> None: ...


def camera_renderer(kind: Literal["raster", "pbr"] | str, shape: ShapeLike, holes: Sequence[Hole], camera: Camera,
                    **cell: Any) -> CameraRenderer:
    """The ``kind`` renderer of ``shape`` seen by ``camera``: ``"raster"`` → ``CameraViewRenderer`` (``cell``:
    its ``supersample``, ``mesh``), ``"pbr"`` → ``PbrRenderer`` (``cell``: ``light``, ``material``, ``sensor``,
    ``spp``, ``max_depth``, ``variant``, ``hole_ends``, ``seed``)."""
    if kind == "raster":
        from cadfeat.render.camera_views import CameraViewRenderer

        return CameraViewRenderer(shape, holes, camera, **cell)
    if kind == "pbr":
        from cadfeat.render.pbr import PbrRenderer

        return PbrRenderer(shape, holes, camera, **cell)
    raise RenderError(f"renderer: {kind!r} is not allowed; allowed: {', '.join(RENDERER_KINDS)}")


def grey_sequence(renderer: CameraRenderer, T_cam_part: np.ndarray) -> np.ndarray:
    """Noiseless grey frames (F, H, W) float32 in 0 … 255 of ``renderer`` at poses ``T_cam_part`` (F, 4, 4) (what
    ``vision.images.render_sequence`` returns for the raster renderer)."""
    T = np.asarray(T_cam_part, dtype=float)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise RenderError(f"T_cam_part must have shape (F, 4, 4), got {T.shape}")
    frames = [renderer.render_grey(pose) for pose in T]
    return np.stack(frames).astype(np.float32) if frames else np.zeros((0, 0, 0), np.float32)
