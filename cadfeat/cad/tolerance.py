"""Tolerances scaled to the model: its size and the file's own precision.

Real STEP exports are not exact to 1e-6 mm: SolidWorks, Fusion 360 and Onshape write the faces of one hole
with axes 1e-6..4e-6 mm / 3e-7..8e-7 rad apart, edge and vertex tolerances of the imported B-rep reach 1e-2 mm
(Fusion 360 fillets), and the files declare a distance accuracy (the STEP ``UNCERTAINTY_MEASURE_WITH_UNIT``)
of 1e-7 to 1e-2 mm. A part 6 m across (an inch model read as mm) needs looser absolute tolerances than a
10 mm spacer. ``ModelTolerance.of_shape`` combines:

- ``linear_mm`` = max(``LINEAR_FLOOR_MM``, ``SIZE_RTOL`` × model diagonal, largest vertex/edge tolerance of the
  B-rep, STEP uncertainty), capped at ``LINEAR_CAP_MM`` (features closer than that are one feature);
- ``angular_rad`` = max(``ANGULAR_FLOOR_RAD``, 2 × ``linear_mm`` / model diagonal) (two axes ``linear_mm``
  apart at both ends of the model);

used for grouping faces into holes, coaxiality, matching and the re-drilling checks.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape, Workplane
    from OCP.TopoDS import TopoDS_Shape

__all__ = ["ModelTolerance", "step_uncertainty_mm"]

LINEAR_FLOOR_MM = 1e-5
"""Smallest linear tolerance (mm): 10× the 1e-6 mm that real exports already exceed."""
SIZE_RTOL = 1e-8
"""Linear tolerance relative to the model diagonal (double precision after a few transforms)."""
LINEAR_CAP_MM = 0.02
"""Largest linear tolerance (mm), whatever the file says."""
ANGULAR_FLOOR_RAD = 1e-5
"""Smallest angular tolerance (rad): real exports carry up to 8e-7 rad between the faces of one hole."""


@dataclass(frozen=True)
class ModelTolerance:
    """Tolerances of one model: ``linear_mm`` (coaxial lines, equal radii, points on planes), ``angular_rad``
    (parallel axes and normals), ``size_mm`` (bounding-box diagonal) and where they came from."""

    linear_mm: float = LINEAR_FLOOR_MM
    angular_rad: float = ANGULAR_FLOOR_RAD
    size_mm: float = 0.0
    brep_tol_mm: float = 0.0
    step_uncertainty_mm: float | None = None

    @classmethod
    def of_shape(cls, shape: Shape | Workplane, step_uncertainty: float | None = None) -> ModelTolerance:
        """The tolerances of ``shape`` (cadquery Shape or OCP TopoDS_Shape), optionally with the STEP file's
        uncertainty (mm, ``step_uncertainty_mm``)."""
        occ = shape.wrapped if hasattr(shape, "wrapped") else shape
        size = _diagonal_mm(occ)
        brep = _max_brep_tolerance_mm(occ)
        linear = max(LINEAR_FLOOR_MM, SIZE_RTOL * size, brep, step_uncertainty or 0.0)
        linear = min(linear, LINEAR_CAP_MM)
        angular = max(ANGULAR_FLOOR_RAD, 2.0 * linear / size) if size > 0 else ANGULAR_FLOOR_RAD
        return cls(linear, angular, size, brep, step_uncertainty)

    def describe(self) -> str:
        unc = "none" if self.step_uncertainty_mm is None else f"{self.step_uncertainty_mm:.3g} mm"
        return (f"linear {self.linear_mm:.3g} mm, angular {self.angular_rad:.3g} rad (model {self.size_mm:.4g} mm "
                f"across, B-rep tolerance {self.brep_tol_mm:.3g} mm, STEP uncertainty {unc})")


def _diagonal_mm(occ: TopoDS_Shape) -> float:
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.Add_s(occ, box, False)
    if box.IsVoid():
        return 0.0
    x0, y0, z0, x1, y1, z1 = box.Get()
    return math.sqrt((x1 - x0) ** 2 + (y1 - y0) ** 2 + (z1 - z0) ** 2)


def _max_brep_tolerance_mm(occ: TopoDS_Shape) -> float:
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_VERTEX
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    worst = 0.0
    for kind, cast in ((TopAbs_EDGE, TopoDS.Edge_s), (TopAbs_VERTEX, TopoDS.Vertex_s)):
        explorer = TopExp_Explorer(occ, kind)
        while explorer.More():
            worst = max(worst, BRep_Tool.Tolerance_s(cast(explorer.Current())))
            explorer.Next()
    return worst


_UNCERTAINTY = re.compile(r"UNCERTAINTY_MEASURE_WITH_UNIT\s*\(\s*(?:LENGTH_MEASURE\s*\(\s*)?([-+0-9.Ee]+)")
_INCH = re.compile(r"CONVERSION_BASED_UNIT\s*\(\s*'INCH'", re.IGNORECASE)
_METRE = re.compile(r"SI_UNIT\s*\(\s*(\.[A-Z]+\.|\$)\s*,\s*\.METRE\.\s*\)")
_PREFIX_MM = {".MILLI.": 1.0, ".CENTI.": 10.0, ".DECI.": 100.0, "$": 1000.0, ".MICRO.": 1e-3, ".KILO.": 1e6}


def step_uncertainty_mm(path: str | Path, head_bytes: int = 2_000_000) -> float | None:
    """The smallest distance accuracy declared in a STEP file (``UNCERTAINTY_MEASURE_WITH_UNIT``), in mm.

    The unit is the file's length unit: inch if the file defines one (``CONVERSION_BASED_UNIT('INCH')``),
    else its SI metre with prefix. None if the file declares none (only its first ``head_bytes`` are read).
    """
    with open(path, encoding="latin-1", errors="replace") as fh:
        text = fh.read(head_bytes)
    values = [float(v) for v in _UNCERTAINTY.findall(text)]
    values = [v for v in values if math.isfinite(v) and v > 0]
    if not values:
        return None
    if _INCH.search(text):
        scale = 25.4
    else:
        prefixes = _METRE.findall(text)
        scale = _PREFIX_MM.get(prefixes[0], 1.0) if prefixes else 1.0
    return min(values) * scale
