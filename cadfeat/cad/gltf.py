"""glTF / GLB export of a part with its holes as named nodes (for OCP CAD Viewer / three-cad-viewer and glTF viewers).

``export_glb(shape, holes, path)`` triangulates the B-rep as ``export.export_stl`` does (same chord tolerance,
``export._triangulate``) and splits the triangles by B-rep face: the faces of hole ``H`` (walls, counterbore
floors, countersink cones: every vertex of the face within the hole's entrance radius of its axis and between
its entrance and its depth) form a node named ``H`` (the hole's name: the names cadfeat uses everywhere), all
other faces the node ``part``. Together the nodes are the STL's triangles. Coordinates are in metres, as glTF
requires (cadfeat's millimetres × 0.001), part frame, +Z kept as it is (no Y-up rotation: the part frame is the
study's frame). Written with trimesh.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.cad.export import face_meshes

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole, ShapeLike

__all__ = ["MM_TO_M", "export_glb"]

MM_TO_M = 1e-3


def _owner(vertices: np.ndarray, holes: Sequence[Hole], tol_mm: float) -> int | None:
    """Index of the hole whose volume (entrance radius around the axis, from the entrance rim down to its depth)
    holds every vertex of a face, or None. Faces touching the rim from outside (the host face) extend beyond."""
    for j, h in enumerate(holes):
        c, a = np.asarray(h.centre, float), np.asarray(h.axis, float)
        d = vertices - c
        along = d @ a
        radial = np.linalg.norm(d - along[:, None] * a, axis=-1)
        depth = float(h.depth_mm) if np.isfinite(h.depth_mm) else np.inf
        if np.all(radial <= h.radius_mm + tol_mm) and np.all(along <= tol_mm) and np.all(along >= -depth - tol_mm) \
                and np.any(radial >= min(h.bore_radius_mm, h.radius_mm) - tol_mm):
            return j
    return None


def export_glb(shape: ShapeLike, holes: Sequence[Hole], path: str | os.PathLike[str], tolerance_mm: float = 0.01,
               angular_tolerance_rad: float = 0.1) -> Path:
    """Write ``path`` (.glb): node ``part`` and one node per hole named ``hole.name`` (see the module
    docstring). Returns the path."""
    import trimesh

    path = Path(path)
    groups: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {"part": []}
    names = [h.name or f"H{i + 1}" for i, h in enumerate(holes)]
    for name in names:
        groups.setdefault(name, [])
    tol = max(10 * tolerance_mm, 1e-3)
    for verts, tris in face_meshes(shape, tolerance_mm, angular_tolerance_rad):
        j = _owner(verts, holes, tol) if len(verts) else None
        groups["part" if j is None else names[j]].append((verts, tris))
    scene = trimesh.Scene()
    for name, pieces in groups.items():
        if not pieces:
            continue
        offsets = np.cumsum([0] + [len(v) for v, _ in pieces[:-1]])
        verts = np.concatenate([v for v, _ in pieces]) * MM_TO_M
        tris = np.concatenate([t + o for (_, t), o in zip(pieces, offsets, strict=True)])
        mesh = trimesh.Trimesh(verts, tris, process=False)
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    path.write_bytes(scene.export(file_type="glb"))
    return path
