"""Thesis object, Fig. 5.8: a two-dimensional array of equal holes (Shademan 2005, §5.2.2).

rows × columns through holes, pitch_x along x and pitch_y along y, centred on the origin, on the top
face z = 0 of a 60 × 60 × 4 mm plate. Defaults use the thesis's 1-D array numbers (8.57 mm, 2.5 mm).

Functional / fixed holes: none.
"""

import cadquery as cq

DESCRIPTION = "Thesis Fig. 5.8: 2-D array of holes (rows x columns)"
PARAMETERS = {
    "pitch_x_mm": {"default": 8.57, "bounds": (6.5, 12.0), "unit": "mm", "description": "column spacing (x)"},
    "pitch_y_mm": {"default": 8.57, "bounds": (6.5, 12.0), "unit": "mm", "description": "row spacing (y)"},
    "radius_mm": {"default": 2.5, "bounds": (1.0, 3.0), "unit": "mm", "description": "hole radius"},
    "rows": {"default": 3, "bounds": (1, 4), "unit": "", "description": "number of rows"},
    "columns": {"default": 3, "bounds": (1, 4), "unit": "", "description": "number of columns"},
}
VIEW_DIRECTION = (0.0, 0.0, 1.0)
FIXED_HOLES = "none"
PLATE_MM = (60.0, 60.0, 4.0)


def grid(pitch_x_mm, pitch_y_mm, rows, columns):
    return [((i - (columns - 1) / 2) * pitch_x_mm, (j - (rows - 1) / 2) * pitch_y_mm)
            for j in range(rows) for i in range(columns)]


def build(pitch_x_mm, pitch_y_mm, radius_mm, rows, columns):
    sx, sy, sz = PLATE_MM
    plate = cq.Solid.makeBox(sx, sy, sz, cq.Vector(-sx / 2, -sy / 2, -sz))
    drills = [cq.Solid.makeCylinder(radius_mm, sz + 2, cq.Vector(x, y, -sz - 1))
              for x, y in grid(pitch_x_mm, pitch_y_mm, rows, columns)]
    return cq.Workplane("XY").add(plate.cut(*drills))


def expected_holes(pitch_x_mm, pitch_y_mm, radius_mm, rows, columns):
    x0, y0 = -(columns - 1) * pitch_x_mm / 2, -(rows - 1) * pitch_y_mm / 2
    return [{"centre": (x0 + i * pitch_x_mm, y0 + j * pitch_y_mm, 0.0), "axis": (0.0, 0.0, 1.0),
             "radius_mm": radius_mm} for i in range(columns) for j in range(rows)]


if "show_object" in globals():  # cq-editor
    show_object(build(**{k: v["default"] for k, v in PARAMETERS.items()}))  # noqa: F821
