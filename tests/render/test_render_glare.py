"""The glare maps (``render.glare``): the physical claim g_POSE's glare term rests on, on a small render.

A plate under the ring light, seen at ~42° from 120 mm (the flagship's targets are seen at 33–57°): in machined
aluminium the interior of a blind bore clips (it returns the light to the lens, ``cell.material.
bores_return_light``) and is brighter than a through bore; in grey plastic the blind bore does not clip. The
reduced film projects a point where the full one does, scaled (pixel edges: (u + ½)/k − ½), as
``Camera.project`` of the two cameras says.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mitsuba")
cq = pytest.importorskip("cadquery")

from cadfeat.cad.features import extract_holes  # noqa: E402
from cadfeat.camera import Camera  # noqa: E402
from cadfeat.cell.material import Material, bores_return_light  # noqa: E402
from cadfeat.cell.model import Cell  # noqa: E402
from cadfeat.poses import invert_T, look_at  # noqa: E402
from cadfeat.render.glare import SCALE, glare_maps, reduced  # noqa: E402

CAMERA = Camera(fx=520.0, fy=520.0, cx=79.5, cy=63.5, width=160, height=128, focus_distance_mm=120.0)


def _plate():
    plate = cq.Workplane("XY").box(40, 30, 5).translate((0, 0, -2.5))
    plate = plate.faces(">Z").workplane(centerOption="CenterOfBoundBox").pushPoints([(-9, 0)]).hole(6.0, 3.0)
    return plate.faces(">Z").workplane(centerOption="CenterOfBoundBox").pushPoints([(9, 0)]).hole(6.0).val()


def _grey_at(maps, T, point):
    uv = maps.camera.project(point @ T[:3, :3].T + T[:3, 3])
    return float(maps.grey[0, int(round(uv[1])), int(round(uv[0]))])


@pytest.mark.parametrize("material", ["machined_aluminium", "grey_plastic"])
def test_blind_bores_clip_in_metal_not_in_plastic(material):
    shape = _plate()
    holes = extract_holes(shape, prefer_direction=(0, 0, 1))
    T = invert_T(look_at(np.array([0.0, -80.0, 90.0]), np.zeros(3)))
    maps = glare_maps(shape, holes, CAMERA, T[None], Cell(material=Material(name=material)))
    assert maps.grey.shape == (1, CAMERA.height // SCALE, CAMERA.width // SCALE)
    blind = _grey_at(maps, T, np.array([-9.0, 0.0, -1.5]))    # the bore's middle, 1.5 mm down
    through = _grey_at(maps, T, np.array([9.0, 0.0, -1.5]))
    if bores_return_light(Material(name=material)):
        assert blind >= 250 > through
    else:
        assert blind < 250


def test_reduced_film_projects_where_the_full_one_does():
    half = reduced(CAMERA, 2)
    p = np.array([[3.0, -4.0, 120.0], [-20.0, 15.0, 140.0]])
    np.testing.assert_allclose(half.project(p), (CAMERA.project(p) + 0.5) / 2 - 0.5, atol=1e-9)
