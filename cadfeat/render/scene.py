"""Off-screen PyVista plotters (EGL, no X server) and part meshes with hole faces marked.

Rendering uses VTK's EGL render window (``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow``), so it
works headless on any machine with ``libEGL`` and Mesa's DRI drivers (``tools/ensure_system.sh``);
no X server or xvfb is involved. PyVista and VTK are imported inside the functions, never at
``import cadfeat``.

Units: millimetres, part frame. Colours are RGB tuples in 0..1.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.cad.export import mesh_from_shape
from cadfeat.cad.features import as_shape, holes_to_arrays
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    import pyvista as pv

    from cadfeat.cad.features import Hole, ShapeLike

#: The render window class VTK creates when asked for an OpenGL window.
EGL_WINDOW = "vtkEGLRenderWindow"

PART_GREY = (0.82, 0.82, 0.84)
HOLE_DARK = (0.06, 0.06, 0.07)
BACKGROUND_WHITE = (1.0, 1.0, 1.0)

#: Chord (mm) and angular (rad) tolerances of the camera-view tessellation: a rim polygon of 63 sides
#: lies within 1.3e-3·r of the circle (well under 0.1 px at usual working distances). Finer angles cost a lot
#: (OCCT meshing time grows ~4x from 0.1 to 0.05 rad on a plate with holes).
RENDER_TOLERANCE_MM = 0.01
RENDER_ANGULAR_TOLERANCE_RAD = 0.1
#: Coarser tolerances for overview pictures (part views), where facets below a pixel do not show.
PICTURE_TOLERANCE_MM = 0.05
PICTURE_ANGULAR_TOLERANCE_RAD = 0.15


class RenderError(CadfeatError):
    """Rendering failed (no EGL, empty shape, bad view arguments)."""


def use_egl() -> None:
    """Ask VTK for the headless EGL render window (read when a render window is created)."""
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", EGL_WINDOW)


def new_plotter(size: tuple[int, int], background: Sequence[float] = BACKGROUND_WHITE,
                lighting: str = "light kit") -> pv.Plotter:
    """An off-screen ``pyvista.Plotter`` of ``size = (width, height)`` pixels on an EGL window."""
    use_egl()
    import pyvista as pv

    width, height = (int(s) for s in size)
    if width < 1 or height < 1:
        raise RenderError(f"image size must be positive integers (width, height), got {size!r}")
    try:
        plotter = pv.Plotter(off_screen=True, window_size=(width, height), lighting=lighting)
    except Exception as exc:  # VTK raises generic errors when no OpenGL context can be made
        raise RenderError(f"cannot create an off-screen render window ({exc}); run tools/ensure_system.sh "
                          "to install libEGL and Mesa's DRI drivers") from exc
    plotter.set_background(background)
    return plotter


def screenshot(plotter: pv.Plotter) -> np.ndarray:
    """Render and return the image as a (height, width, 3) uint8 RGB array, rows top-down."""
    plotter.render()
    return np.asarray(plotter.screenshot(return_img=True), dtype=np.uint8)[..., :3]


def shape_polydata(shape: ShapeLike, tolerance_mm: float = RENDER_TOLERANCE_MM,
                   angular_tolerance_rad: float = RENDER_ANGULAR_TOLERANCE_RAD) -> pv.PolyData:
    """Triangle mesh of a B-rep (``cadquery`` Shape / Workplane) as ``pyvista.PolyData`` (mm, part frame)."""
    import pyvista as pv

    mesh = mesh_from_shape(as_shape(shape), tolerance_mm, angular_tolerance_rad)
    if len(mesh.faces) == 0:
        raise RenderError("the shape has no faces to render")
    faces = np.hstack([np.full((len(mesh.faces), 1), 3, dtype=np.int64), mesh.faces]).ravel()
    return pv.PolyData(np.asarray(mesh.vertices, dtype=float), faces)


def hole_cell_labels(mesh: pv.PolyData, holes: Sequence[Hole], tol_mm: float = 1e-3) -> np.ndarray:
    """For each triangle the index of the hole whose surface it belongs to, −1 for the rest (N_cells,).

    A triangle belongs to hole j when its centroid lies inside the hole's entrance cylinder
    (distance to the axis ≤ radius_mm + tol) strictly below the entrance rim plane and not below
    the hole's depth (the exit face of a through hole is excluded). Batched over triangles × holes.
    """
    n_cells = mesh.n_cells
    labels = np.full(n_cells, -1, dtype=int)
    if not holes or n_cells == 0:
        return labels

    centres, axes, radii = holes_to_arrays(holes)
    depth = np.array([h.depth_mm for h in holes])
    through = np.array([h.through for h in holes])
    p = np.asarray(mesh.cell_centers().points)                      # (C, 3)
    d = p[:, None, :] - centres[None, :, :]                           # (C, N, 3)
    t = np.einsum("cnk,nk->cn", d, axes)                              # along the outward axis
    radial = np.linalg.norm(d - t[..., None] * axes[None], axis=-1)
    low = np.where(through, -depth + tol_mm, -depth - tol_mm)
    inside = (radial <= radii + tol_mm) & (t < -tol_mm) & (t > low)
    hit = inside.any(axis=1)
    labels[hit] = np.argmax(inside[hit], axis=1)
    return labels


def cell_colours(labels: np.ndarray, hole_colours: Sequence[Sequence[float]] | None,
                 part: Sequence[float] = PART_GREY, hole: Sequence[float] = HOLE_DARK) -> np.ndarray:
    """(N_cells, 3) uint8 RGB colours: ``part`` grey, hole j in ``hole_colours[j]`` (default dark)."""
    rgb = np.tile(np.asarray(part, dtype=float), (len(labels), 1))
    in_hole = labels >= 0
    if hole_colours is None:
        rgb[in_hole] = hole
    else:
        table = np.asarray(hole_colours, dtype=float).reshape(-1, 3)
        rgb[in_hole] = table[labels[in_hole]]
    return np.round(rgb * 255).astype(np.uint8)


def add_part(plotter: pv.Plotter, mesh: pv.PolyData, colours: np.ndarray, **kwargs: Any) -> Any:
    """Add a part mesh coloured per triangle (flat shading, so the faces keep crisp edges)."""
    mesh = mesh.copy()
    mesh.cell_data["rgb"] = colours
    return plotter.add_mesh(mesh, scalars="rgb", rgb=True, smooth_shading=False, show_scalar_bar=False, **kwargs)
