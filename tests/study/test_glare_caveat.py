"""The raster check's caveat in a metal cell (``study.closed_loop_check.glare_caveat``, issue 28).

The raster renderer paints every bore dark; under physical light a blind bore in machined aluminium returns the
light to the lens. Seen head-on under a coaxial light, the face around it mirrors the light too (the highlight is
centred under the lens, over the blind hole), and the blind rim has no contrast left: the physical render itself
(``PbrRenderer``, full resolution, the maps' metered exposure) shows it — the bore's interior and the face around
it read within 15 grey levels — and the caveat names that hole, not the through hole (which shows the dark
fixture behind). In grey plastic, or for a check that renders physically, there is no caveat.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("mitsuba")
cq = pytest.importorskip("cadquery")

from cadfeat.cad.features import extract_holes  # noqa: E402
from cadfeat.camera import Camera  # noqa: E402
from cadfeat.cell.light import Light  # noqa: E402
from cadfeat.cell.material import Material  # noqa: E402
from cadfeat.cell.model import Cell  # noqa: E402
from cadfeat.poses import invert_T, look_at  # noqa: E402
from cadfeat.render.glare import glare_maps  # noqa: E402
from cadfeat.render.pbr import PbrRenderer  # noqa: E402
from cadfeat.render.sensor import Sensor  # noqa: E402
from cadfeat.study.closed_loop_check import glare_caveat  # noqa: E402

CAMERA = Camera(fx=520.0, fy=520.0, cx=79.5, cy=63.5, width=160, height=128, focus_distance_mm=120.0)
LIGHT = Light(kind="coaxial", reference_mm=120.0)


def _plate():
    plate = cq.Workplane("XY").box(40, 30, 5).translate((0, 0, -2.5))
    plate = plate.faces(">Z").workplane(centerOption="CenterOfBoundBox").pushPoints([(-6, 0)]).hole(6.0, 3.0)
    return plate.faces(">Z").workplane(centerOption="CenterOfBoundBox").pushPoints([(7, 0)]).hole(6.0).val()


def _case(material: str):
    shape = _plate()
    holes = extract_holes(shape, prefer_direction=(0, 0, 1))
    eyes = [np.array([-6.0 + dx, 0.0, 120.0]) for dx in (-1.0, 0.0, 1.0)]  # above the blind hole
    T = np.stack([invert_T(look_at(e, e * [1.0, 1.0, 0.0], up=(0.0, 1.0, 0.0))) for e in eyes])
    cell = Cell(material=Material(name=material), light=LIGHT)
    maps = glare_maps(shape, holes, CAMERA, T, cell)
    config = SimpleNamespace(cell=cell)
    delivery = SimpleNamespace(setup=SimpleNamespace(problem=SimpleNamespace(glare=maps, T_cam_part=T)),
                               designs=lambda: {"before": (shape, holes), "after": (shape, holes)})
    return shape, holes, T, cell, config, delivery


def _contrast(image: np.ndarray, centre_px: np.ndarray, radius_px: float) -> float:
    """|median grey inside the rim (0.6 r) − median grey on the face around it (1.3–1.8 r)| of ``image``."""
    v, u = np.mgrid[:image.shape[0], :image.shape[1]]
    rho = np.hypot(u - centre_px[0], v - centre_px[1])
    return abs(float(np.median(image[rho < 0.6 * radius_px]) - np.median(image[(rho > 1.3 * radius_px)
                                                                                  & (rho < 1.8 * radius_px)])))


def test_a_blind_rim_without_contrast_in_metal_is_named():
    shape, holes, T, cell, config, delivery = _case("machined_aluminium")
    blind = next(h for h in holes if not h.through)
    through = next(h for h in holes if h.through)
    with PbrRenderer(shape, holes, CAMERA, light=cell.light, material=cell.material, spp=16,
                     sensor=Sensor(exposure="meter")) as r:                 # exposed as the maps are
        image = r.render_grey(T[1])
    radius_px = CAMERA.fx * blind.radius_mm / 120.0
    centre = lambda h: CAMERA.project((np.asarray(h.centre) @ T[1][:3, :3].T + T[1][:3, 3])[None])[0]  # noqa: E731
    assert _contrast(image, centre(blind), radius_px) < 15.0 < _contrast(image, centre(through), radius_px)
    caveat = glare_caveat(config, delivery, "fast", "raster")
    assert caveat is not None
    assert set(caveat["holes"]) == {"before", "after"}
    assert list(caveat["holes"]["before"]) == [blind.name] and caveat["holes"]["before"][blind.name] >= 0.5
    assert "--track pbr" in caveat["warning"] and blind.name in caveat["warning"]
    assert glare_caveat(config, delivery, "pbr", "pbr") is None


def test_no_caveat_in_plastic():
    *_, config, delivery = _case("grey_plastic")
    assert glare_caveat(config, delivery, "fast", "raster") is None
