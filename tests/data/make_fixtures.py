"""Build the small STEP fixtures of tests/data (run: ``python tests/data/make_fixtures.py``).

``plate_holes.step``: an 80 x 60 x 10 mm plate (top face at z = 10) with two plain through holes, a
counterbore, a 90° countersink and a blind hole. The construction values below are the tests' reference.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
PLATE = (80.0, 60.0, 10.0)  # x, y, z size in mm; the plate spans z in [0, 10], centred in x and y
# name -> (x, y) on the top face, entrance diameter, kind-specific values (mm / degrees)
PLAIN = {"A": ((-25.0, -15.0), 8.0), "B": ((-25.0, 15.0), 6.0)}     # through, diameter
CBORE = ((20.0, -12.0), 6.0, 11.0, 4.0)                            # bore dia, cbore dia, cbore depth
CSINK = ((20.0, 14.0), 5.0, 10.0, 90.0)                            # bore dia, csink dia, angle (deg)
BLIND = ((0.0, 0.0), 5.0, 6.0)                                     # diameter, depth
STEP_NAME = "plate_holes.step"


def build_plate(skip: tuple[str, ...] = (), moved: dict[str, tuple[tuple[float, float], float]] | None = None):
    """The fixture plate as a cadquery Solid. ``skip`` leaves out holes by name ("A", "B", "CBORE", "CSINK",
    "BLIND"); ``moved`` replaces a hole's (x, y) and entrance diameter (the tests' direct CAD reference for
    re-drilling: ``HoleProfile.resized`` — a counterbore or countersink changes its entrance, its bore stays)."""
    import cadquery as cq

    moved = moved or {}
    wp = cq.Workplane("XY").box(*PLATE, centered=(True, True, False))

    def top(w):
        return w.faces(">Z").workplane(centerOption="ProjectedOrigin", origin=(0, 0, 0))

    for name, (xy, dia) in PLAIN.items():
        if name not in skip:
            xy, dia = moved.get(name, (xy, dia))
            wp = top(wp).pushPoints([xy]).hole(dia)
    if "CBORE" not in skip:
        xy, bore, cbore, depth = CBORE
        xy, new = moved.get("CBORE", (xy, cbore))
        wp = top(wp).pushPoints([xy]).cboreHole(bore, new, depth)
    if "CSINK" not in skip:
        xy, bore, csink, angle = CSINK
        xy, new = moved.get("CSINK", (xy, csink))
        wp = top(wp).pushPoints([xy]).cskHole(bore, new, angle)
    if "BLIND" not in skip:
        xy, dia, depth = BLIND
        xy, dia = moved.get("BLIND", (xy, dia))
        wp = top(wp).pushPoints([xy]).hole(dia, depth)
    return wp.val()


def main() -> None:
    sys.path.insert(0, str(HERE.parents[1]))
    from cadfeat.cad.export import export_step

    path = export_step(build_plate(), HERE / STEP_NAME, write_pcurves=False)
    print(f"wrote {path} ({path.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
