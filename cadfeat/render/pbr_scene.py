"""Mitsuba 3 scene pieces for ``render.pbr``: the variant, the part mesh, the sensor and the lights.

Mitsuba is imported inside the functions (``import cadfeat.render`` stays light) and its variant is process
global: ``use_variant`` chooses it once (``llvm_ad_rgb`` when its LLVM back end loads, else ``scalar_rgb``) and
caches the choice; asking for another variant later switches the whole process (objects of the former variant
must not be used any more).

Frames and units: millimetres, part frame; the OpenCV camera frame (x right, y down, z forward). Mitsuba's
camera looks along its +z with x to the left and y up, so its ``to_world`` is ``T_part_cam · diag(−1, −1, 1, 1)``.
Film coordinates: Mitsuba's pixel k covers [k, k + 1) and a ray through film position x_f maps to the OpenCV
coordinate x_f − ½ once the principal point offset is ``(W/2 − (cx + ½)) / W`` (measured with
``Sensor.sample_ray``; the same for y with H and cy), so OpenCV's pixel centres (integers) are Mitsuba's.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.cell.light import Light, emitter_strength
from cadfeat.errors import CadfeatError
from cadfeat.poses import invert_T

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import ShapeLike
    from cadfeat.results import JsonDict

__all__ = ["PREFERRED_VARIANTS", "annulus_mesh", "emitter_mesh_ply", "light_dicts", "part_mesh_arrays", "sampler_dict",
           "sensor_dict", "use_variant", "write_ply"]

#: Variants tried in order when none is asked for: LLVM's JIT (vectorised, all cores), then plain C++.
PREFERRED_VARIANTS = ("llvm_ad_rgb", "scalar_rgb")
#: Mitsuba's camera axes in the OpenCV camera frame: x left, y up, z forward.
MITSUBA_FROM_OPENCV = np.diag([-1.0, -1.0, 1.0, 1.0])
_variant_cache: list[str] = []


def use_variant(variant: str | None = None) -> str:
    """Set (once) and return the Mitsuba variant: ``variant`` if given, else the first of ``PREFERRED_VARIANTS``
    that loads. The choice is cached: later calls without ``variant`` return it without touching Mitsuba."""
    import mitsuba as mi

    if variant is None and _variant_cache:
        return _variant_cache[0]
    for name in (variant,) if variant is not None else PREFERRED_VARIANTS:
        try:
            if mi.variant() != name:
                mi.set_variant(name)
            mi.load_dict({"type": "diffuse"})  # the LLVM back end is loaded on first use: fail here, not later
        except (ImportError, AttributeError, RuntimeError) as exc:
            if variant is not None:
                raise CadfeatError(f"Mitsuba variant {variant!r} does not load here ({exc}); allowed: one of "
                                   f"{', '.join(mi.variants())}") from exc
            continue
        _variant_cache[:] = [name]
        return name
    raise CadfeatError(f"no Mitsuba variant of {PREFERRED_VARIANTS} loads; install libLLVM or a Mitsuba wheel "
                       f"with scalar_rgb")


def part_mesh_arrays(shape: ShapeLike, tolerance_mm: float, angular_tolerance_rad: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (V, 3) mm, triangles (T, 3) and unit vertex normals (V, 3) of a B-rep solid.

    Each B-rep face keeps its own vertices (``cad.export.face_meshes``), so the normals (area-weighted means of
    the face's triangle normals) are smooth within a face — a bore's wall shades round — and sharp across the
    edges between faces (a rim stays a crisp edge).
    """
    from cadfeat.cad.export import face_meshes
    from cadfeat.cad.features import as_shape

    faces = face_meshes(as_shape(shape), tolerance_mm, angular_tolerance_rad)
    if not faces:
        raise CadfeatError("the shape has no faces to render")
    offsets = np.cumsum([0] + [len(v) for v, _ in faces[:-1]])
    vertices = np.concatenate([v for v, _ in faces])
    tris = np.concatenate([t + o for (_, t), o in zip(faces, offsets, strict=True)])
    a, b, c = (vertices[tris[:, i]] for i in range(3))
    area_normals = np.cross(b - a, c - a)                       # |n| = twice the triangle's area
    normals = np.zeros_like(vertices)
    for i in range(3):
        np.add.at(normals, tris[:, i], area_normals)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return vertices, tris, normals / np.where(length > 0, length, 1.0)


def annulus_mesh(inner_mm: float, outer_mm: float, segments: int = 96) -> tuple[np.ndarray, np.ndarray]:
    """An annulus (a disc when ``inner_mm`` = 0) in the z = 0 plane, triangles wound so their normal is +z:
    vertices (2S, 3) mm and triangles (2S, 3). The polygon's area equals the circles' (radii scaled by
    √(2π / (S sin(2π/S)))), so its irradiance is the annulus's."""
    s = np.arange(segments)
    phi = 2 * np.pi * s / segments
    k = math.sqrt(2 * math.pi / (segments * math.sin(2 * math.pi / segments)))
    ring = np.stack([np.cos(phi), np.sin(phi), np.zeros(segments)], axis=1) * k
    vertices = np.concatenate([ring * max(inner_mm, 1e-6 * outer_mm), ring * outer_mm])
    nxt = (s + 1) % segments
    tris = np.concatenate([np.stack([s, segments + s, segments + nxt], axis=1),
                           np.stack([s, segments + nxt, nxt], axis=1)])
    return vertices, tris


def write_ply(path: str | Path, vertices: np.ndarray, triangles: np.ndarray,
              normals: np.ndarray | None = None) -> Path:
    """A binary little-endian PLY of a triangle mesh (float32 positions mm, optional vertex normals)."""
    path = Path(path)
    props = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals is not None else [])
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(vertices)}",
              *(f"property float {p}" for p in props), f"element face {len(triangles)}",
              "property list uchar int vertex_indices", "end_header"]
    cols = vertices if normals is None else np.hstack([vertices, normals])
    face = np.zeros(len(triangles), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    face["n"], face["i"] = 3, triangles
    with path.open("wb") as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        fh.write(np.ascontiguousarray(cols, dtype="<f4").tobytes())
        fh.write(face.tobytes())
    return path


def sensor_dict(width: int, height: int, fx: float, cx: float, cy: float, T_cam_part: np.ndarray, *,
                spp: int, near_far_mm: tuple[float, float], crop: tuple[int, int, int, int] | None = None
                ) -> JsonDict:
    """A Mitsuba ``perspective`` sensor with square pixels of focal length ``fx`` px, principal point (cx, cy)
    (OpenCV pixels) and a ``width`` × ``height`` film with a box filter (each pixel is the mean over its area),
    at pose ``T_cam_part`` (4, 4). ``crop`` = (x, y, w, h) renders only that window of the film."""
    import mitsuba as mi

    film: JsonDict = {"type": "hdrfilm", "width": int(width), "height": int(height),
                            "rfilter": {"type": "box"}, "pixel_format": "rgb", "component_format": "float32"}
    if crop is not None:
        film.update(crop_offset_x=int(crop[0]), crop_offset_y=int(crop[1]), crop_width=int(crop[2]),
                    crop_height=int(crop[3]))
    return {"type": "perspective", "fov_axis": "x", "fov": math.degrees(2 * math.atan(width / (2 * fx))),
            "principal_point_offset_x": (width / 2 - (cx + 0.5)) / width,
            "principal_point_offset_y": (height / 2 - (cy + 0.5)) / height,
            "near_clip": float(near_far_mm[0]), "far_clip": float(near_far_mm[1]),
            "to_world": mi.ScalarTransform4f(invert_T(np.asarray(T_cam_part, float)) @ MITSUBA_FROM_OPENCV),
            "sampler": sampler_dict(spp), "film": film}


def sampler_dict(spp: int) -> JsonDict:
    """Stratified samples (jittered on a √spp × √spp grid: pixel coverage, hence edges, converge fastest) when
    ``spp`` is a power of 4 (what Mitsuba's ``stratified`` takes without rounding), else independent ones."""
    power_of_4 = spp > 0 and spp & (spp - 1) == 0 and (spp.bit_length() - 1) % 2 == 0
    return {"type": "stratified" if power_of_4 else "independent", "sample_count": int(spp)}


def _area_light(filename: Path, T_part_cam: np.ndarray, radiance: float) -> JsonDict:
    import mitsuba as mi

    return {"type": "ply", "filename": str(filename), "to_world": mi.ScalarTransform4f(T_part_cam),
            "face_normals": True, "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [radiance] * 3}}}


def light_dicts(light: Light, T_cam_part: np.ndarray, emitter_ply: Path | None) -> JsonDict:
    """The scene entries of ``light`` at camera pose ``T_cam_part`` (the ring and the coaxial disc move with the
    camera; ``emitter_ply`` is their mesh in the camera frame, ``annulus_mesh``), plus the ambient term."""
    import mitsuba as mi

    out: JsonDict = {}
    strength = emitter_strength(light)
    T_part_cam = invert_T(np.asarray(T_cam_part, float))
    if light.kind in ("ring", "coaxial") and strength > 0:
        if emitter_ply is None:
            raise CadfeatError(f"a {light.kind} light needs its emitter mesh")
        out["light"] = _area_light(emitter_ply, T_part_cam, strength)
    elif light.kind == "spot" and strength > 0:
        to_world = mi.ScalarTransform4f().look_at(origin=list(light.position_mm), target=list(light.target_mm),
                                                  up=_up_for(np.subtract(light.target_mm, light.position_mm)))
        out["light"] = {"type": "spot", "to_world": to_world, "cutoff_angle": light.cutoff_deg,
                        "beam_width": min(light.beam_deg, light.cutoff_deg),
                        "intensity": {"type": "rgb", "value": [strength] * 3}}
    dome = background_radiance(light)
    if dome > 0:
        out["dome"] = {"type": "constant", "radiance": {"type": "rgb", "value": [dome] * 3}}
    return out


def background_radiance(light: Light) -> float:
    """Radiance of the constant environment (a dome's, plus ``ambient`` / π): what a camera ray that misses the
    part reads (the ring, the coaxial disc and a spot are not seen directly)."""
    return (emitter_strength(light) if light.kind == "dome" else 0.0) + light.ambient / math.pi


def _up_for(direction: np.ndarray) -> list[float]:
    """An up vector not parallel to ``direction`` (for ``look_at``)."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    return [0.0, 0.0, 1.0] if abs(d[2]) < 0.9 else [0.0, 1.0, 0.0]


def emitter_mesh_ply(light: Light, path: Path) -> Path | None:
    """The ring's annulus or the coaxial disc (camera frame, facing +z) as a PLY at ``path``; None otherwise."""
    if light.kind == "ring":
        return write_ply(path, *annulus_mesh(light.inner_radius_mm, light.outer_radius_mm))
    if light.kind == "coaxial":
        return write_ply(path, *annulus_mesh(0.0, light.radius_mm))
    return None


