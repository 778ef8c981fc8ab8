"""The robot cell as one model (docs/design.md "The cell is one model").

The camera's mount tolerance, the part's placement tolerance, the light and the sensor, the part's material and
finish, how its holes are made, and the detector with its gate: declared once, each number saying whether it is a
± bound or a standard deviation. The same ``Cell`` reaches g_POSE's models (``measures.pose_models``), the robust
draws (``design.robust``) and the closed loop (``vision``). It sits on the lowest floor, beside ``camera.py``:
measures, design, render and vision all read it, and it imports none of them.

``cadfeat.cell.defaults`` holds the default cell's numbers with no imports (the lower layers' defaults are these);
the ``Cell`` model (pydantic) is imported on first use of a name below.
"""

from typing import TYPE_CHECKING

__all__ = ["BOUND_KEYS", "DETECTORS", "HOLE_ENDS", "PER_AXIS", "PLACEMENT_SIGMA_PER_TOLERANCE", "SIGMA_KEYS", "Cell",
           "per_axis", "triple"]

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cell.model import (
        BOUND_KEYS,
        DETECTORS,
        HOLE_ENDS,
        PER_AXIS,
        PLACEMENT_SIGMA_PER_TOLERANCE,
        SIGMA_KEYS,
        Cell,
        per_axis,
        triple,
    )


def __getattr__(name: str) -> object:
    """The model's names, imported on first use (PEP 562): ``cadfeat.cell.defaults`` stays free of pydantic."""
    if name in __all__:
        from cadfeat.cell import model

        return getattr(model, name)
    raise AttributeError(f"module 'cadfeat.cell' has no attribute {name!r}")
