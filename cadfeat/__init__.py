"""cadfeat — redesign the hole features of CAD parts for vision-guided manipulation.

Implements the measures of Shademan (2005), *Optimal Feature Design for Vision-Guided Manipulation*,
on real CAD models. ``import cadfeat`` stays light: CadQuery and PyVista are imported lazily by the
modules that need them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from cadfeat.camera import Camera

__version__ = "0.1.0"
__all__ = ["Camera", "run_study", "__version__"]

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.study import StudyResult


def run_study(path_or_dict: Any, out_dir: Any = None, **kwargs: Any) -> StudyResult:
    """Run a redesign study (a TOML path or a dict) and write its outputs; see ``cadfeat.study``."""
    from cadfeat.study import run_study as _run_study

    return _run_study(path_or_dict, out_dir, **kwargs)
