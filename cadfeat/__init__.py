"""cadfeat — redesign the hole features of CAD parts for vision-guided manipulation.

Implements the measures of Shademan (2005), *Optimal Feature Design for Vision-Guided Manipulation*,
on real CAD models. ``import cadfeat`` stays light: CadQuery and PyVista are imported lazily by the
modules that need them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from cadfeat._version import __version__

__all__ = ["Camera", "__version__", "extract_holes", "load_part", "load_step", "redrill", "run_study"]

#: Public CAD names, imported on first use from ``cadfeat.cad`` (CadQuery is heavy).
_CAD_NAMES = ("extract_holes", "load_part", "load_step", "redrill")

if TYPE_CHECKING:  # pragma: no cover (for the type checker: the functions themselves)
    from cadfeat.cad.features import extract_holes
    from cadfeat.cad.parts import load_part
    from cadfeat.cad.step_parts import load_step, redrill
    from cadfeat.camera import Camera
    from cadfeat.study.run import run_study
else:
    def run_study(path_or_dict, out_dir=None, **kwargs):
        """Run a redesign study (a TOML path or a dict) and write its outputs; see ``cadfeat.study.run``."""
        from cadfeat.study.run import run_study as _run_study  # lazy: keeps `import cadfeat` light

        return _run_study(path_or_dict, out_dir, **kwargs)


def __getattr__(name: str) -> object:
    if name == "Camera":  # numpy: imported on first use, so that `cadfeat --help` stays fast
        from cadfeat.camera import Camera

        return Camera
    if name in _CAD_NAMES:
        from cadfeat import cad

        return getattr(cad, name)
    raise AttributeError(f"module 'cadfeat' has no attribute {name!r}")
