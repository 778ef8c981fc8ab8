"""The geometric design matrix of part scripts (finite differences of extracted holes).

References: closed-form derivatives of the drawings (a bolt circle: ∂c/∂R = (cos a, sin a, 0),
∂c/∂φ = R(-sin a, cos a, 0)); the scripts' ``expected_holes`` at other parameter values (the prediction
of a linear map must equal them); a hand-written script with a parameter that moves no hole.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cadfeat.cad.design_map import design_map
from cadfeat.cad.features import holes_to_arrays
from cadfeat.cad.parts import PARTS_DIR, load_part
from cadfeat.errors import CadfeatError

HUB_NAMES = ["bolt_circle_radius_mm", "phase_rad", "small_hole_radius_mm", "centre_hole_radius_mm"]


@pytest.fixture(scope="module")
def hub_map():
    hub = load_part(PARTS_DIR / "thesis_hub.py")
    return hub, design_map(hub, HUB_NAMES, at={"phase_rad": 0.2, "bolt_circle_radius_mm": 10.0})


def test_hub_map_against_closed_form(hub_map):
    hub, dm = hub_map
    c0, _, r0 = holes_to_arrays(dm.holes0)
    centre = int(np.argmin(np.linalg.norm(c0, axis=1)))
    small = [i for i in range(len(c0)) if i != centre]
    assert dm.moved_by == {"bolt_circle_radius_mm": small, "phase_rad": small, "small_hole_radius_mm": small,
                           "centre_hole_radius_mm": [centre]}
    assert dm.unused == []
    a = np.arctan2(c0[small, 1], c0[small, 0])
    radial = np.stack([np.cos(a), np.sin(a), 0 * a], axis=1)
    tangential = 10.0 * np.stack([-np.sin(a), np.cos(a), 0 * a], axis=1)
    np.testing.assert_allclose(dm.dC[small, :, 0], radial, atol=1e-9)
    np.testing.assert_allclose(dm.dC[small, :, 1], tangential, atol=1e-5)  # central FD error R h²/6
    np.testing.assert_allclose(dm.dR[small, 2], 1.0, atol=1e-9)
    np.testing.assert_allclose(dm.dR[centre], [0, 0, 0, 1], atol=1e-9)
    np.testing.assert_allclose(dm.dA, 0.0, atol=1e-12)
    assert dm.linear_by == {"bolt_circle_radius_mm": True, "phase_rad": False, "small_hole_radius_mm": True,
                            "centre_hole_radius_mm": True}
    assert not dm.linear
    # the phase deviation at the 0.1 rad check step is the chord sagitta-like term R(1 - cos h) ≈ R h²/2
    assert dm.deviation_mm["phase_rad"] == pytest.approx(10.0 * 0.1**2 / 2, rel=0.02)
    assert dm.n_builds == 1 + 3 * len(HUB_NAMES)


def test_hub_prediction_equals_rebuild_for_linear_parameters(hub_map):
    hub, dm = hub_map
    new = {"bolt_circle_radius_mm": 13.5, "small_hole_radius_mm": 1.7, "centre_hole_radius_mm": 4.0}
    centres, axes, radii = dm.predict(new)
    expected = hub.expected_holes(**{**dm.at, **new})
    ec = np.array([e["centre"] for e in expected])
    for c, r in zip(centres, radii, strict=True):
        j = int(np.argmin(np.linalg.norm(ec - c, axis=1)))
        assert np.linalg.norm(ec[j] - c) < 1e-8
        assert abs(expected[j]["radius_mm"] - r) < 1e-8
    np.testing.assert_allclose(axes, np.tile([0.0, 0.0, 1.0], (len(axes), 1)))
    X = np.array([[dm.at[n] for n in dm.names], [13.5, 0.2, 1.7, 4.0]])
    bc, ba, br = dm.predict_batch(X)
    np.testing.assert_allclose(bc[1], centres, atol=1e-12)
    np.testing.assert_allclose(br[1], radii, atol=1e-12)
    np.testing.assert_allclose(bc[0], holes_to_arrays(dm.holes0)[0], atol=1e-12)
    with pytest.raises(CadfeatError, match="unknown parameter.*allowed: bolt_circle_radius_mm"):
        dm.predict({"hole_count": 3})


def test_flange_targets_nonlinear_fixed_holes_never_move():
    flange = load_part(PARTS_DIR / "pipe_flange_dn50.py")
    dm = design_map(flange, list(flange.parameters))
    c0, _, _ = holes_to_arrays(dm.holes0)
    targets = sorted(i for i, h in enumerate(dm.holes0) if abs(np.hypot(*h.centre[:2]) - 66.0) < 1e-9)
    assert len(targets) == 2
    assert all(sorted(v) == targets for v in dm.moved_by.values())
    assert dm.linear_by == {"target_circle_radius_mm": True, "target_angle_rad": False, "target_radius_mm": True}


def test_one_sided_at_bounds_and_linear_parts():
    square = load_part(PARTS_DIR / "thesis_square_points.py")
    dm = design_map(square, ["side_mm"], at={"side_mm": 6.0})  # upper bound: one-sided difference
    assert dm.linear and dm.check_steps[0] < 0
    c0, _, _ = holes_to_arrays(dm.holes0)
    np.testing.assert_allclose(dm.dC[:, :, 0], c0 / 6.0, atol=1e-9)  # corners (±d/2, ±d/2, 0)
    nema = load_part(PARTS_DIR / "nema17_mount.py")
    dm = design_map(nema, ["base_hole_x_mm", "target_face_z_mm"])
    c0, _, _ = holes_to_arrays(dm.holes0)
    base = sorted(i for i, c in enumerate(c0) if abs(abs(c[0]) - 29.0) < 1e-9 and abs(c[1] - 45.0) < 1e-9)
    assert dm.moved_by["base_hole_x_mm"] == base
    np.testing.assert_allclose(dm.dC[base, :, 0], [[-1, 0, 0], [1, 0, 0]] if c0[base[0], 0] < 0
                               else [[1, 0, 0], [-1, 0, 0]], atol=1e-9)
    face = [i for i, c in enumerate(c0) if abs(c[0] - 28.0) < 1e-9]
    assert dm.moved_by["target_face_z_mm"] == face and dm.linear


def test_unused_parameter_and_errors(tmp_path):
    script = tmp_path / "plate.py"
    script.write_text(
        "import cadquery as cq\n"
        "PARAMETERS = {'x_mm': {'default': 0.0, 'bounds': (-5, 5)},\n"
        "              'thickness_mm': {'default': 4.0, 'bounds': (2, 8)}, 'n': {'default': 1, 'bounds': (1, 2)}}\n"
        "def build(x_mm, thickness_mm, n):\n"
        "    plate = cq.Solid.makeBox(30, 30, thickness_mm, cq.Vector(-15, -15, -thickness_mm))\n"
        "    drills = [cq.Solid.makeCylinder(2, 20, cq.Vector(x_mm + 8 * k, 0, -10)) for k in range(n + (x_mm > 4))]\n"
        "    return plate.cut(*drills)\n")
    part = load_part(script)
    dm = design_map(part, ["x_mm", "thickness_mm"])
    assert dm.unused == ["thickness_mm"] and dm.moved_by["x_mm"] == [0] and dm.linear
    with pytest.raises(CadfeatError, match="integer parameter.*n cannot be in a design map"):
        design_map(part, ["n"])
    with pytest.raises(CadfeatError, match="unknown or repeated.*allowed: x_mm, thickness_mm, n"):
        design_map(part, ["y_mm"])
    with pytest.raises(CadfeatError, match="number of holes"):
        design_map(part, ["x_mm"], at={"x_mm": 3.95})  # the check step crosses x = 4: a second hole appears
    assert math.isfinite(dm.deviation_mm["x_mm"])


def test_axis_derivative_of_a_tilting_hole(tmp_path):
    """A hole drilled at angle θ about y through a fixed entrance point: axis (sin θ, 0, cos θ), so
    ∂axis/∂θ = (cos θ, 0, -sin θ) (closed form); the centre does not move; the map is nonlinear in θ."""
    script = tmp_path / "tilt.py"
    script.write_text(
        "import math\nimport cadquery as cq\n"
        "PARAMETERS = {'tilt_rad': {'default': 0.3, 'bounds': (0.0, 0.6), 'unit': 'rad'},\n"
        "              'x_mm': {'default': 0.0, 'bounds': (-5, 5)}}\n"
        "def build(tilt_rad, x_mm):\n"
        "    plate = cq.Solid.makeBox(40, 40, 10, cq.Vector(-20, -20, -10))\n"
        "    axis = cq.Vector(math.sin(tilt_rad), 0, math.cos(tilt_rad))\n"
        "    start = cq.Vector(x_mm, 0, 0) + axis * 2\n"
        "    return plate.cut(cq.Solid.makeCylinder(2.0, 8.0, start, -axis))\n")
    dm = design_map(load_part(script), ["tilt_rad", "x_mm"])
    np.testing.assert_allclose(dm.holes0[0].axis, [math.sin(0.3), 0, math.cos(0.3)], atol=1e-12)
    np.testing.assert_allclose(dm.dA[0, :, 0], [math.cos(0.3), 0, -math.sin(0.3)], atol=1e-6)
    np.testing.assert_allclose(dm.dC[0, :, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(dm.dC[0, :, 1], [1, 0, 0], atol=1e-9)
    assert dm.moved_by == {"tilt_rad": [0], "x_mm": [0]}
    assert dm.linear_by == {"tilt_rad": False, "x_mm": True}
    _, axes, _ = dm.predict({"tilt_rad": 0.35})
    np.testing.assert_allclose(axes[0], [math.sin(0.35), 0, math.cos(0.35)], atol=1e-3)


def test_worker_builds_give_the_same_map_and_feature_matrix():
    """Builds in time-limited worker processes (BRep transfer) give the same map as in-process builds."""
    part = load_part(PARTS_DIR / "thesis_single_hole.py")
    local = design_map(part, ["hole_x_mm", "radius_mm"])
    remote = design_map(part, ["hole_x_mm", "radius_mm"], timeout_s=120)
    np.testing.assert_allclose(remote.dC, local.dC, atol=1e-12)
    np.testing.assert_allclose(remote.dR, local.dR, atol=1e-12)
    rows, matrix = local.feature_matrix()
    assert rows == ["H1.x", "H1.y", "H1.z", "H1.r"]
    np.testing.assert_allclose(matrix, [[1, 0], [0, 0], [0, 0], [0, 1]], atol=1e-9)  # uncoupled (§2.2.4)


def test_linear_feature_model_from_design_map(hub_map):
    """The optimiser's LinearFeatureModel built from a DesignMap predicts what the map predicts."""
    from cadfeat.design.design_space import LinearFeatureModel

    _, dm = hub_map
    x0 = [dm.at[n] for n in dm.names]
    model = LinearFeatureModel.from_design_map(dm, list(dm.names), x0)
    x = np.array(x0) + np.array([1.0, 0.05, -0.3, 0.2])
    c, a, r = model.features(x)
    pc, pa, pr = dm.predict(dict(zip(dm.names, x, strict=True)))
    np.testing.assert_allclose(c, pc, atol=1e-12)
    np.testing.assert_allclose(a, pa, atol=1e-12)
    np.testing.assert_allclose(r, pr, atol=1e-12)
