"""The CAD side of the data flow: part scripts, STEP parts, hole extraction, the design map, export.

``part script / STEP ──build──▶ B-rep solid ──extract──▶ holes``, and back: the design map ∂F/∂P (eq. 2.2,
geometric level) and the verified STEP/STL export of a rebuilt design.

- ``parts``: parametric CadQuery part scripts (``load_part``, time-limited ``build_shape``);
- ``step_parts``: STEP parts and re-drilling of their holes (``load_step``, ``redrill``);
- ``features``: hole extraction from the B-rep (``extract_holes``, ``match_holes``);
- ``design_map``: features as a function of the part parameters (∂F/∂P by central differences);
- ``export``: STEP/STL export in millimetres and round-trip verification.

The public names below are imported lazily (CadQuery is heavy), so ``import cadfeat.cad`` stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover (the names ``__getattr__`` gives, for the type checker)
    from cadfeat.cad.features import Hole, extract_holes
    from cadfeat.cad.parts import load_part
    from cadfeat.cad.step_parts import load_step, redrill

__all__ = ["Hole", "extract_holes", "load_part", "load_step", "redrill"]

_HOMES = {
    "Hole": "cadfeat.cad.features",
    "extract_holes": "cadfeat.cad.features",
    "load_part": "cadfeat.cad.parts",
    "load_step": "cadfeat.cad.step_parts",
    "redrill": "cadfeat.cad.step_parts",
}


def __getattr__(name: str) -> object:
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module 'cadfeat.cad' has no attribute {name!r}")
