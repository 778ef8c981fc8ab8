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
from typing import Any

import numpy as np

__all__ = ["MM_TO_M", "export_glb", "face_meshes"]

MM_TO_M = 1e-3


def face_meshes(shape: Any, tolerance_mm: float = 0.01,
                angular_tolerance_rad: float = 0.1) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per B-rep face: vertices (V, 3) mm and triangles (T, 3) oriented out of the material, from the same
    triangulation as ``export_stl`` with these tolerances."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    from cadfeat.cad.export import ExportError, _occ_shape, _triangulate

    occ = _occ_shape(shape)
    _triangulate(occ, tolerance_mm, angular_tolerance_rad)
    out = []
    explorer = TopExp_Explorer(occ, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face_s(explorer.Current())
        explorer.Next()
        loc = TopLoc_Location()
        poly = BRep_Tool.Triangulation_s(face, loc)
        if poly is None:
            raise ExportError("a face could not be triangulated")
        trsf = loc.Transformation()
        nodes = [poly.Node(i).Transformed(trsf) for i in range(1, poly.NbNodes() + 1)]
        tri = np.array([poly.Triangle(i).Get() for i in range(1, poly.NbTriangles() + 1)], dtype=np.int64) - 1
        if face.Orientation() == TopAbs_REVERSED:
            tri = tri[:, ::-1]
        out.append((np.array([(p.X(), p.Y(), p.Z()) for p in nodes], dtype=float).reshape(-1, 3), tri.reshape(-1, 3)))
    return out


def _owner(vertices: np.ndarray, holes: Sequence[Any], tol_mm: float) -> int | None:
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


def export_glb(shape: Any, holes: Sequence[Any], path: str | os.PathLike[str], tolerance_mm: float = 0.01,
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
