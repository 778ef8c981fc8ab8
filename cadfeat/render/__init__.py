"""Off-screen renders (PyVista on EGL): part views before/after and synthetic camera images; physically based
camera images (Mitsuba 3, ``render.pbr.PbrRenderer``), both behind ``render.interface.CameraRenderer``.

``import cadfeat.render`` is light: PyVista, VTK and CadQuery are imported inside the functions.
"""

from __future__ import annotations

from cadfeat.render.camera_views import CameraViewRenderer, draw_hole_overlay, render_camera_views
from cadfeat.render.interface import RENDERER_KINDS, CameraRenderer, camera_renderer, grey_sequence
from cadfeat.render.part_views import render_comparison, render_part
from cadfeat.render.scene import RenderError, new_plotter, shape_polydata, use_egl

__all__ = ["RENDERER_KINDS", "CameraRenderer", "CameraViewRenderer", "RenderError", "camera_renderer",
           "draw_hole_overlay", "grey_sequence", "new_plotter", "render_camera_views", "render_comparison",
           "render_part", "shape_polydata", "use_egl"]
