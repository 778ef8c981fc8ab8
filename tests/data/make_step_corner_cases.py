"""Write the STEP corner-case fixtures (tests/data/corner_cases/*.step): parts made by cadfeat's own CAD code
that reproduce, one trait each, what real exports from other CAD systems look like (measured on a local
corpus of 26 third-party parts from SolidWorks, Fusion 360, Onshape, FreeCAD, Creo, Inventor, NX; see the
docs/results.md "Real STEP parts"). Run: ``python tests/data/make_step_corner_cases.py``.

Every part is a 60 × 40 × 8 mm plate (top face z = 8) unless said otherwise; construction values are the
module constants, which the tests use as their independent reference.

- ``split_walls``: SolidWorks writes a hole wall as two 180° faces — a plain hole, a counterbore and a
  countersink each cut by two half solids of revolution.
- ``offset_faces``: the two halves (and the countersink cone vs. its bore) 3e-6 mm and 5e-7 rad apart, as in
  real exports (1e-6..4e-6 mm, 3e-7..8e-7 rad): four identical countersinks.
- ``filleted_rim`` / ``chamfered_rim``: a plain through hole whose entrance rim is filleted (1 mm) or
  chamfered (0.4 mm).
- ``near_round``: a 3-D-printing teardrop (270° arc + a point) and a D-bore (a flat at 0.6 r): not holes.
- ``freeform``: a plate whose outline is a spline (B-spline side faces: whole-solid volumes from OCCT's
  default integration are off by more than 1e-6 relative) with two plain holes.
- ``far_from_origin``: the split-wall plate 1.5 m from the origin.
- ``crowded_step``: a counterbore whose step floor a slot from the top also cuts (Onshape, Fusion 360 parts):
  still one counterbore.
- ``grooved``: a plain hole with an annular groove round it on the top face: the groove (a full concave wall
  round a boss) is no hole, and the face between them is no step.
- ``set_screw``: a block with a Ø12 bore and a radial set-screw hole from the +x face into it: a through hole
  whose two ends look alike; the camera side decides its entrance (not inside the bore).
- ``slot_cut``: a plain hole whose wall a pocket from the bottom cuts into (3 mm up): it is found (its upper
  wall is a full circle) but cannot be re-drilled; the dry run must refuse it.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

HERE = Path(__file__).parent
OUT = HERE / "corner_cases"

PLATE = (60.0, 40.0, 8.0)
T = PLATE[2]
PLAIN = ((-18.0, 0.0), 6.0)                       # (x, y), diameter
CBORE = ((0.0, 0.0), 3.4, 6.5, 3.3)               # (x, y), bore, counterbore diameter, depth
CSINK = ((18.0, 0.0), 3.4, 6.6, 90.0)             # (x, y), bore, countersink diameter, angle (deg)
CSINKS = ((-20.0, -10.0), (-7.0, 10.0), (7.0, -10.0), (20.0, 10.0))
OFFSET_MM, TILT_RAD = 3e-6, 5e-7
FILLET = ((0.0, 0.0), 6.0, 1.0)                   # (x, y), bore diameter, fillet radius
CHAMFER = ((0.0, 0.0), 6.0, 0.4)                  # (x, y), bore diameter, chamfer length
TEARDROP = ((-12.0, 0.0), 5.0)                    # (x, y), diameter (270° arc, point up +y)
DBORE = ((12.0, 0.0), 6.0, 0.6)                   # (x, y), diameter, flat at this fraction of the radius
FREEFORM_HOLES = (((-10.0, 0.0), 5.0), ((12.0, 2.0), 4.0))
FAR = (1500.0, 0.0, 0.0)
CROWDED = ((0.0, 0.0), 3.4, 6.5, 3.3, (4.0, 0.0), 6.0, 1.5, 4.0)  # counterbore; slot centre, length, width, depth
GROOVE = ((0.0, 0.0), 4.0, 5.0, 6.0, 1.0)          # hole (x, y), diameter; groove inner/outer radius, depth
SET_SCREW = ((30.0, 30.0, 20.0), 12.0, 2.5, 10.0)  # block; bore Ø (along z); set-screw Ø (along +x); its z
SLOT = ((0.0, 0.0), 6.0, (0.0, -3.0), 2.0, 3.0)   # hole (x, y), diameter; pocket centre, width, height (mm)


def _plate():
    import cadquery as cq

    return cq.Workplane("XY").box(*PLATE, centered=(True, True, False)).val()


def _half_revolutions(points, centre, axis=(0.0, 0.0, -1.0), offset=(0.0, 0.0, 0.0), tilt=0.0):
    """Two 180° solids of revolution of the half-section ``points`` [(radius, depth)...] about the axis
    through ``centre`` (depth along ``axis``); the second half's axis shifted by ``offset`` (mm) and tilted by
    ``tilt`` (rad, about x)."""
    import cadquery as cq

    def solid(start_deg, shift, angle):
        c = cq.Vector(*centre) + cq.Vector(*shift)
        a = cq.Vector(*axis)
        a = cq.Vector(a.x, a.y * math.cos(angle) - a.z * math.sin(angle), a.y * math.sin(angle) + a.z * math.cos(angle))
        ref = cq.Vector(math.cos(math.radians(start_deg)), math.sin(math.radians(start_deg)), 0.0)
        radial = (ref - a * ref.dot(a)).normalized()
        pts = [c + radial * r + a * t for r, t in points]
        axis_pts = [c + a * points[-1][1], c + a * points[0][1]]
        face = cq.Face.makeFromWires(cq.Wire.makePolygon(pts + axis_pts, close=True))
        return cq.Solid.revolve(face, 180.0, c, c + a)

    return [solid(0.0, (0.0, 0.0, 0.0), 0.0), solid(180.0, offset, tilt)]


def _cut(shape, tools):
    for tool in tools:
        shape = shape.cut(tool)
    return shape


def _section(kind: str, bore: float, entrance: float, extra: float, depth: float = T + 1.0):
    """Half-section [(radius, depth)] of a through hole (depth from the top face + 0.5 mm above it)."""
    a = -0.5
    if kind == "plain":
        return [(bore / 2, a), (bore / 2, depth)]
    if kind == "counterbore":
        return [(entrance / 2, a), (entrance / 2, extra), (bore / 2, extra), (bore / 2, depth)]
    h = (entrance / 2 - bore / 2) / math.tan(math.radians(extra) / 2)
    return [(entrance / 2 + 0.5 * math.tan(math.radians(extra) / 2), a), (bore / 2, h), (bore / 2, depth)]


def split_walls(offset: float = 0.0, tilt: float = 0.0):
    (pxy, pd), (cxy, cb, cd, cdepth), (sxy, sb, sd, sang) = PLAIN, CBORE, CSINK
    shape = _plate()
    for xy, sec in ((pxy, _section("plain", pd, pd, 0)), (cxy, _section("counterbore", cb, cd, cdepth)),
                    (sxy, _section("countersink", sb, sd, sang))):
        shape = _cut(shape, _half_revolutions(sec, (*xy, T), offset=(offset, 0.0, 0.0), tilt=tilt))
    return shape


def offset_faces():
    """Four split-wall countersinks; ``perturb_step`` then moves the surfaces apart in the written file."""
    _, sb, sd, sang = CSINK
    shape = _plate()
    for xy in CSINKS:
        shape = _cut(shape, _half_revolutions(_section("countersink", sb, sd, sang), (*xy, T)))
    return shape


def perturb_step(text: str) -> str:
    """Shift the axis of every conical surface by ``OFFSET_MM`` along x and tilt it by ``TILT_RAD`` about x,
    and shift every second cylindrical surface by −``OFFSET_MM``: the faces of one hole then disagree as in
    real exports, while the topology (shared edges) stays."""
    import re

    ents = dict(re.findall(r"^#(\d+) = (.*?);\s*$", text, flags=re.M | re.S))
    lines = {k: v for k, v in ents.items()}
    seen_cyl = 0
    for v in ents.values():
        m = re.match(r"(CONICAL|CYLINDRICAL)_SURFACE\('',#(\d+)", v)
        if not m:
            continue
        if m.group(1) == "CYLINDRICAL":
            seen_cyl += 1
            if seen_cyl % 2:
                continue
        ax = re.match(r"AXIS2_PLACEMENT_3D\('',#(\d+),#(\d+),#(\d+)\)", ents[m.group(2)])
        pid, did = ax.group(1), ax.group(2)
        x, y, z = (float(c) for c in re.search(r"\(([^()]*)\)\s*\)", ents[pid]).group(1).split(","))
        dx = OFFSET_MM if m.group(1) == "CONICAL" else -OFFSET_MM
        lines[pid] = f"CARTESIAN_POINT('',({x + dx!r},{y!r},{z!r}))"
        if m.group(1) == "CONICAL":
            a, b, c = (float(q) for q in re.search(r"\(([^()]*)\)\s*\)", ents[did]).group(1).split(","))
            ct, st = math.cos(TILT_RAD), math.sin(TILT_RAD)
            lines[did] = f"DIRECTION('',({a!r},{b * ct - c * st!r},{b * st + c * ct!r}))"
    for k, v in lines.items():
        if v != ents[k]:
            text = re.sub(rf"^#{k} = .*?;\s*$", f"#{k} = {v};\n", text, count=1, flags=re.M | re.S)
    return text


def rimmed(kind: str, xy=None, bore=None):
    """The plate with one plain through hole whose top rim is filleted or chamfered (cadquery)."""
    import cadquery as cq

    (x0, y0), d, size = FILLET if kind == "fillet" else CHAMFER
    x, y = xy if xy is not None else (x0, y0)
    d = bore if bore is not None else d
    wp = cq.Workplane("XY").box(*PLATE, centered=(True, True, False))
    wp = wp.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)).pushPoints([(x, y)]).hole(d)
    edges = wp.edges(cq.selectors.NearestToPointSelector((x + d / 2, y, T)))
    return (edges.fillet(size) if kind == "fillet" else edges.chamfer(size)).val()


FILLET_BOTH = (7.0, 6.0, 1.0)                       # plate thickness; hole diameter; fillet radius at both rims


def filleted_both_ends(xy=(0.0, 0.0)):
    """A 7 mm plate with one Ø6 through hole at ``xy`` whose rims are filleted r1 at BOTH ends (the hole wall is
    then a 5 mm cylinder between two quarter tori)."""
    import cadquery as cq

    t, d, r = FILLET_BOTH
    x, y = xy
    wp = cq.Workplane("XY").box(PLATE[0], PLATE[1], t, centered=(True, True, False))
    wp = wp.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)).pushPoints([(x, y)]).hole(d)
    for z in (t, 0.0):
        wp = wp.edges(cq.selectors.NearestToPointSelector((x + d / 2, y, z))).fillet(r)
    return wp.val()


def near_round():
    import cadquery as cq

    (tx, ty), td = TEARDROP
    r = td / 2
    tip = (tx, ty + r * math.sqrt(2))
    a1 = (tx + r * math.cos(math.radians(45)), ty + r * math.sin(math.radians(45)))
    a2 = (tx - r * math.cos(math.radians(45)), ty + r * math.sin(math.radians(45)))
    tear = (cq.Workplane("XY").moveTo(*a1).threePointArc((tx, ty - r), a2).lineTo(*tip).close()
            .extrude(T + 2).translate((0, 0, -1)))
    (dx, dy), dd, frac = DBORE
    rd = dd / 2
    h = frac * rd
    w = math.sqrt(rd * rd - h * h)
    dbore = (cq.Workplane("XY").moveTo(dx - w, dy + h).threePointArc((dx, dy - rd), (dx + w, dy + h)).close()
             .extrude(T + 2).translate((0, 0, -1)))
    return _plate().cut(tear.val()).cut(dbore.val())


def freeform(holes=FREEFORM_HOLES):
    import cadquery as cq

    L, W, _ = PLATE
    pts = [(-L / 2, -W / 2), (0, -W / 2 - 3), (L / 2, -W / 2), (L / 2 + 2, 0), (L / 2, W / 2), (0, W / 2 + 4),
           (-L / 2, W / 2), (-L / 2 - 3, 0)]
    wp = cq.Workplane("XY").spline(pts, periodic=True).close().extrude(T)
    for xy, d in holes:
        wp = wp.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)).pushPoints([xy]).hole(d)
    return wp.val()


def far_from_origin():
    import cadquery as cq

    return split_walls().moved(cq.Location(cq.Vector(*FAR)))


def slot_cut():
    import cadquery as cq

    xy, d, sxy, sw, sh = SLOT
    wp = cq.Workplane("XY").box(*PLATE, centered=(True, True, False))
    wp = wp.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)).pushPoints([xy]).hole(d)
    slot = cq.Workplane("XY").center(*sxy).rect(sw, 4.0).extrude(sh + 1).translate((0, 0, -1))
    return wp.val().cut(slot.val())


def crowded_step():
    import cadquery as cq

    xy, bore, cb, depth, sxy, length, width, sdepth = CROWDED
    wp = cq.Workplane("XY").box(*PLATE, centered=(True, True, False))
    wp = wp.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)).pushPoints([xy]).cboreHole(
        bore, cb, depth)
    slot = cq.Workplane("XY").center(*sxy).rect(length, width).extrude(sdepth + 1).translate((0, 0, T - sdepth))
    return wp.val().cut(slot.val())


def grooved():
    import cadquery as cq

    xy, d, r_in, r_out, depth = GROOVE
    wp = cq.Workplane("XY").box(*PLATE, centered=(True, True, False))
    wp = wp.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0)).pushPoints([xy]).hole(d)
    ring = (cq.Workplane("XY").center(*xy).circle(r_out).circle(r_in).extrude(depth + 1)
            .translate((0, 0, T - depth)))
    return wp.val().cut(ring.val())


def set_screw():
    import cadquery as cq

    (bx, by, bz), bore, screw, z = SET_SCREW
    block = cq.Workplane("XY").box(bx, by, bz, centered=(True, True, False))
    block = block.cut(cq.Workplane("XY").circle(bore / 2).extrude(bz + 2).translate((0, 0, -1)))
    radial = cq.Workplane("YZ").center(0.0, z).circle(screw / 2).extrude(bx)
    return block.cut(radial).val()


CASES = {"split_walls": split_walls, "offset_faces": offset_faces,
         "filleted_rim": lambda: rimmed("fillet"), "chamfered_rim": lambda: rimmed("chamfer"),
         "near_round": near_round, "freeform": freeform, "far_from_origin": far_from_origin, "slot_cut": slot_cut,
         "crowded_step": crowded_step, "grooved": grooved, "set_screw": set_screw,
         "filleted_both_ends": filleted_both_ends}


def main() -> None:
    sys.path.insert(0, str(HERE.parents[1]))
    from cadfeat.cad.export import export_step

    OUT.mkdir(exist_ok=True)
    for name, build in CASES.items():
        path = export_step(build(), OUT / f"{name}.step", write_pcurves=False)
        if name == "offset_faces":
            path.write_text(perturb_step(path.read_text()))
        print(f"wrote {path} ({path.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
