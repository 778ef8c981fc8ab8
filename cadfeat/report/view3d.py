"""Interactive, offline 3-D before/after view inside report.html (three.js r147, vendored, inlined).

``view3d_section(context, results)`` returns an HTML fragment: a canvas with the part before and after
(triangulated B-rep, part frame, mm), a "before / after" switch, the camera path and frusta, every hole
labelled, and a hole's measures (results.json ``measures.*.per_feature``) shown on hover or click. Rotate:
left drag; zoom: wheel; pan: right drag (three.js ``OrbitControls``).

Everything is in the page: three.js and OrbitControls (``vendor/three-0.147.0``, MIT) are inlined as classic
scripts and the scene as JSON with base64 float32/uint32 arrays, so the view works with no network and from a
mailed file. The page exposes ``window.cadfeat3d`` = {show(which), which(), snapshot()} for tests (snapshot:
mean, standard deviation and a checksum of the canvas pixels).
"""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.cad.features import as_shape
from cadfeat.report.context import ReportContext
from cadfeat.results import FeatureSummary, Measures, Results, section, value

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape, Workplane

    from cadfeat.results import JsonDict


VENDOR = Path(__file__).parent / "vendor" / "three-0.147.0"
#: Number of camera frusta drawn along the path.
N_FRUSTA = 5


def _b64(a: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype=dtype).tobytes()).decode("ascii")


def mesh_arrays(shape: Shape | Workplane) -> tuple[np.ndarray, np.ndarray]:
    """Triangulated B-rep: vertices (V, 3) mm and triangles (T, 3), tolerance 0.2 % of the bounding box."""
    s = as_shape(shape)
    bb = s.BoundingBox()
    tol = max(1e-3, 0.002 * float(np.linalg.norm([bb.xlen, bb.ylen, bb.zlen])))
    verts, tris = s.tessellate(tol, 0.3)
    v = np.array([(p.x, p.y, p.z) for p in verts], float).reshape(-1, 3)
    return v, np.asarray(tris, np.int64).reshape(-1, 3)


def _holes(holes: Any, per_feature: list[FeatureSummary], fixed: Any) -> list[JsonDict]:
    out: list[JsonDict] = []
    feats = {f.index: f for f in per_feature}
    for i, h in enumerate(holes or []):
        f = feats.get(i)
        measures = {k: v for k in ("fov_min", "fov_px_min", "focus_min", "resolution_px_min", "visible_frac",
                                   "worst_pose") if (v := getattr(f, k, None)) is not None}
        out.append({"name": h.name or (f.name if f else None) or f"H{i + 1}",
                    "centre": np.asarray(h.centre, float).tolist(),
                    "axis": np.asarray(h.axis, float).tolist(), "radius": float(h.radius_mm),
                    "fixed": bool(fixed[i]) if fixed is not None and i < len(fixed) else False,
                    "measures": measures})
    return out


def _per_feature(m: Measures | None, which: str) -> list[FeatureSummary]:
    design = None if m is None else m.before if which == "before" else m.after
    return design.per_feature if design is not None else []


def _camera_path(context: ReportContext, results: Results, scale: float) -> JsonDict:
    """Camera centres (L, 3) and N_FRUSTA frusta (4 far corners each) in the part frame (mm)."""
    if context.trajectory is None:
        return {}
    from cadfeat.poses import invert_T  # lazy: would import scipy.spatial at module load

    T_task_part = np.eye(4) if context.T_task_part is None else np.asarray(context.T_task_part, float)
    T_part_cam = invert_T(T_task_part) @ np.asarray(context.trajectory.T_task_cam, float)
    path = T_part_cam[:, :3, 3]
    cam = value(results, "camera") or {}
    if context.camera is not None:
        cam = {k: getattr(context.camera, k) for k in ("fx", "fy", "cx", "cy", "width", "height")}
    frusta = []
    if all(k in cam for k in ("fx", "fy", "cx", "cy", "width", "height")):
        d = 0.12 * scale
        uv = np.array([[0, 0], [cam["width"], 0], [cam["width"], cam["height"]], [0, cam["height"]]], float)
        corners = np.column_stack([(uv[:, 0] - cam["cx"]) / cam["fx"] * d, (uv[:, 1] - cam["cy"]) / cam["fy"] * d,
                                   np.full(4, d)])
        for k in np.unique(np.linspace(0, len(path) - 1, N_FRUSTA).round().astype(int)):
            R, t = T_part_cam[k, :3, :3], T_part_cam[k, :3, 3]
            frusta.append({"apex": t.tolist(), "corners": (corners @ R.T + t).tolist()})
    return {"path": path.tolist(), "frusta": frusta}


def scene_data(context: ReportContext, results: Results) -> JsonDict:
    """The scene as plain data (meshes base64 float32 / uint32)."""
    m = section(results, "measures", Measures)
    designs = {}
    pairs = [("before", context.shape_before, context.holes_before), ("after", context.shape_after,
                                                                        context.holes_after)]
    scale = 1.0
    for which, shape, holes in pairs:
        if shape is None:
            continue
        v, t = mesh_arrays(shape)
        scale = max(scale, float(np.ptp(v, axis=0).max()) if len(v) else 1.0)
        designs[which] = {"vertices": _b64(v, "<f4"), "triangles": _b64(t, "<u4"), "n_vertices": len(v),
                          "n_triangles": len(t),
                          "holes": _holes(holes, _per_feature(m, which), context.fixed_mask)}
    if "before" in designs and "after" in designs:  # which holes the design changes (index correspondence)
        hb, ha = designs["before"]["holes"], designs["after"]["holes"]
        for b, a in zip(hb, ha, strict=False):
            changed = bool(np.linalg.norm(np.subtract(a["centre"], b["centre"])) > 1e-6
                           or abs(a["radius"] - b["radius"]) > 1e-6)
            a["changed"] = b["changed"] = changed
    return {"designs": designs, "camera": _camera_path(context, results, scale), "scale": scale}


_CSS = """
#view3d{position:relative;width:100%;max-width:1100px;height:560px;border:1px solid #ccc;background:#f7f7f7}
#view3d canvas{display:block;width:100%;height:100%}
#view3d .bar{position:absolute;top:8px;left:8px;background:rgba(255,255,255,.9);padding:4px 8px;
border:1px solid #ccc;font-size:.9em;z-index:2}
#view3d .lbl{position:absolute;font:12px sans-serif;background:rgba(255,255,255,.8);padding:0 3px;
border:1px solid #888;pointer-events:none;white-space:nowrap;z-index:1}
#view3d .info{position:absolute;right:8px;top:8px;background:rgba(255,255,255,.95);border:1px solid #888;
padding:6px 10px;font-size:.85em;min-width:190px;z-index:2}
"""

_JS = Path(__file__).with_name("view3d.js")


def view3d_section(context: ReportContext | None, results: Results) -> str:
    """The interactive view (empty string without shapes in the context)."""
    if context is None or context.shape_before is None:
        return ""
    data = json.dumps(scene_data(context, results), separators=(",", ":")).replace("</", "<\\/")
    three = (VENDOR / "three.min.js").read_text(encoding="utf-8")
    orbit = (VENDOR / "OrbitControls.js").read_text(encoding="utf-8")
    has_after = context.shape_after is not None
    switch = ('<label><input type="radio" name="view3d-which" value="before"> before</label> '
              '<label><input type="radio" name="view3d-which" value="after" checked> after</label>') if has_after \
        else "current design"
    switch += (' &nbsp; <button type="button" id="view3d-part">part</button> '
               '<button type="button" id="view3d-fit">part + camera path</button>')
    return (f"<style>{_CSS}</style>"
            "<p>Drag to rotate, wheel to zoom, right-drag to pan; hover or click a hole for its measures "
            "(worst over the trajectory). Holes: orange = will move (before), green = moved (after), blue = fixed, "
            "dark = unchanged. \"part + camera path\" frames the camera path (violet) and frusta (grey) too.</p>"
            f'<div id="view3d"><div class="bar">{switch}</div><div class="info" id="view3d-info" '
            'style="display:none"></div></div>'
            f'<script type="application/json" id="view3d-data">{data}</script>'
            f"<script>{three}</script><script>{orbit}</script><script>{_JS.read_text(encoding='utf-8')}</script>")
