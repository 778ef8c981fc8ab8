"""Image Jacobian, diagnostics and resolvability against independent references: central finite
differences of ``Camera.project`` under small camera motions (se3_exp in the camera frame), the §4.3
closed-form singular values of one point, numpy's pinv/svd, and the thesis cube of §5.4.3."""

from __future__ import annotations

import numpy as np
import pytest
from numerics import assert_close_rel, sigma_rtol

from cadfeat import measures
from cadfeat.camera import Camera
from cadfeat.poses import invert_T, se3_exp, transform_points

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)

RNG = np.random.default_rng(4927)

DISTS = [(0.0, 0.0, 0.0, 0.0, 0.0), (-0.21, 0.08, 0.0013, -0.0021, -0.012)]


def _camera(dist=(0.0, 0.0, 0.0, 0.0, 0.0)) -> Camera:
    return Camera(fx=812.3, fy=809.1, cx=331.0, cy=247.5, width=640, height=480, dist=dist)


def _points(n: int) -> np.ndarray:
    z = RNG.uniform(80.0, 600.0, n)
    x = RNG.uniform(-0.4, 0.4, n) * z
    y = RNG.uniform(-0.3, 0.3, n) * z
    return np.stack([x, y, z], axis=-1)


def _moved_projection(camera: Camera, points: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """Pixels of fixed points after the camera moves by ``twist`` (camera frame): T_cam' = T_cam @ exp(ξ)."""
    return camera.project(transform_points(invert_T(se3_exp(twist)), points))


@pytest.mark.parametrize("dist", DISTS)
def test_image_jacobian_matches_finite_differences_of_project(dist):
    cam = _camera(dist)
    pts = _points(40)
    J = measures.image_jacobian(cam, pts)
    assert J.shape == (40, 2, 6)
    h = 1e-5
    for k in range(6):
        xi = np.zeros(6)
        xi[k] = h
        fd = (_moved_projection(cam, pts, xi) - _moved_projection(cam, pts, -xi)) / (2 * h)
        np.testing.assert_allclose(J[..., k], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_image_jacobian_random_screw_direction():
    cam = _camera(DISTS[1])
    pts = _points(25)
    screw = RNG.normal(size=6) * np.array([10.0, 10.0, 10.0, 0.05, 0.05, 0.05])
    h = 1e-4
    fd = (_moved_projection(cam, pts, h * screw) - _moved_projection(cam, pts, -h * screw)) / (2 * h)
    np.testing.assert_allclose(measures.image_jacobian(cam, pts) @ screw, fd, rtol=1e-6, atol=1e-7 * np.abs(fd).max())


def test_camera_moving_forward_makes_points_spread():
    """Sign convention: moving towards the scene (v_z > 0) moves off-centre points outwards."""
    cam = _camera()
    p = np.array([50.0, 0.0, 300.0])
    flow = measures.image_jacobian(cam, p) @ np.array([0, 0, 1.0, 0, 0, 0])
    assert flow[0] > 0


def test_one_point_closed_form_singular_values():
    """§4.3: the position block of one point has singular values f/Z and f‖P‖/Z² (fx = fy, no distortion)."""
    f = 700.0
    cam = Camera(fx=f, fy=f, cx=320.0, cy=240.0, width=640, height=480)
    pts = _points(30)
    J = measures.image_jacobian(cam, pts)[..., :3]
    sv = np.linalg.svd(J, compute_uv=False)
    Z = pts[:, 2]
    expected = np.stack([f * np.linalg.norm(pts, axis=-1) / Z**2, f / Z], axis=-1)
    np.testing.assert_allclose(sv, expected, rtol=1e-10)


def _stacked(cam, L=7, N=5):
    pts = _points(L * N).reshape(L, N, 3)
    return measures.stacked_jacobian(cam, pts), pts


def test_diagnostics_match_numpy_svd():
    cam = _camera(DISTS[1])
    J, _ = _stacked(cam)
    d = measures.jacobian_diagnostics(J)
    sv = np.linalg.svd(J, compute_uv=False)
    rel = sigma_rtol(sv[:, 0] / sv[:, -1])  # σ from eigvalsh(JᵀJ): relative round-off ε·cond² (tests/numerics.py)
    assert_close_rel(d["sigma_min"], sv[:, -1], rel, "σ_min")
    assert_close_rel(d["condition"], sv[:, 0] / sv[:, -1], rel, "condition")
    assert_close_rel(d["manipulability"], np.prod(sv, axis=-1), 6 * rel, "manipulability")
    assert not d["singular"].any()


def test_two_points_are_singular_and_weights_remove_rows():
    cam = _camera()
    pts = _points(8).reshape(2, 4, 3)
    w = np.array([[1, 1, 0, 0], [1, 1, 1, 1.0]])
    J = measures.stacked_jacobian(cam, pts, w)
    assert J.shape == (2, 8, 6)
    np.testing.assert_array_equal(J[0, 4:], 0.0)
    d = measures.jacobian_diagnostics(J)
    assert d["singular"].tolist() == [True, False]
    assert np.isfinite(d["condition"]).all()


@pytest.mark.parametrize("ell", [1.0, 25.0])
def test_resolvability_identity_and_pinv_definition(ell):
    """Λ = 1/‖J̃⁺D‖ (eq. 4.32, numpy pinv) = ‖Jγ̇‖/‖γ̃‖ for full column rank."""
    cam = _camera(DISTS[1])
    J, _ = _stacked(cam)
    screws = RNG.normal(size=(J.shape[0], 6)) * [5, 5, 5, 0.1, 0.1, 0.1]
    lam = measures.resolvability(J, screws, rotation_length_mm=ell)
    scale = np.array([1, 1, 1, ell, ell, ell])
    Js = J / scale
    for k in range(J.shape[0]):
        flow = J[k] @ screws[k]
        D = flow / np.linalg.norm(flow)
        assert lam[k] == pytest.approx(1.0 / np.linalg.norm(np.linalg.pinv(Js[k]) @ D), rel=1e-8)
        assert lam[k] == pytest.approx(np.linalg.norm(flow) / np.linalg.norm(screws[k] * scale), rel=1e-10)


def test_resolvability_rank_deficient_uses_pinv():
    cam = _camera()
    pts = _points(8).reshape(4, 2, 3)  # two points: rank 4
    J = measures.stacked_jacobian(cam, pts)
    screws = RNG.normal(size=(4, 6))
    lam = measures.resolvability(J, screws)
    for k in range(4):
        flow = J[k] @ screws[k]
        expected = 1.0 / np.linalg.norm(np.linalg.pinv(J[k], rcond=1e-6) @ (flow / np.linalg.norm(flow)))
        assert lam[k] == pytest.approx(expected, rel=1e-8)
    # rank deficiency: Λ ≥ the full-rank identity value (J⁺J projects γ̇)
    assert np.all(lam >= np.linalg.norm(np.einsum("lmk,lk->lm", J, screws), axis=-1)
                  / np.linalg.norm(screws, axis=-1) * (1 - 1e-9))
    zero = measures.resolvability(np.zeros((2, 8, 6)), RNG.normal(size=(2, 6)))
    np.testing.assert_array_equal(zero, 0.0)


def _cube(d: float) -> np.ndarray:
    """The eight corners of the thesis cube of edge d (eq. 5.1), part frame, mm."""
    s = np.array([[x, y, z] for x in (1, -1) for y in (1, -1) for z in (1, -1)], dtype=float)
    return 0.5 * d * s


def test_resolvability_grows_with_cube_edge():
    """§5.4.3 (Fig. 5.10 c): for the 3-D cube, H = Σ_k Λ_k (eq. 4.33) grows quasi-linearly with the edge d along
    an approach that looks at the cube (library ``straight_approach``, analytic screws with rotation)."""
    from cadfeat.trajectory import straight_approach

    cam = Camera.preset("dalsa-cad1-128a").without_distortion()
    traj = straight_approach(start=(-8.0, 2.0, 58.0), end=(8.0, -2.0, 34.0), target=(0.0, 0.0, 0.0), n=30,
                             duration_s=3.0)
    screws = traj.velocity_screws()
    assert np.abs(screws[:, 3:]).max() > 0.01  # the camera turns to keep looking at the cube
    T_cam_part = invert_T(traj.T_task_cam)
    for ell in (1.0, 30.0):
        H = []
        for d in (1.41, 2.0, 3.0, 4.0, 5.0, 6.0):
            J = measures.stacked_jacobian(cam, transform_points(T_cam_part[:, None], _cube(d)[None]))
            assert not measures.jacobian_diagnostics(J)["singular"].any()
            H.append(measures.resolvability(J, screws, rotation_length_mm=ell).sum())
        assert np.all(np.diff(H) > 0), H
        slope = np.diff(H) / np.diff([1.41, 2.0, 3.0, 4.0, 5.0, 6.0])
        assert slope.max() < 1.3 * slope.min()  # quasi-linear, as in the thesis


@pytest.mark.parametrize("dist", [(0, 0, 0, 0, 0), (-0.3, 0, 0, 0, 0), (-0.2, 0.05, 0, 0, 0),
                                  (-0.21, 0.08, 0.0013, -0.0021, -0.012), (0.1, 0.0, 0.002, 0.001, 0.0)])
def test_lens_kernel_matches_camera(dist):
    from cadfeat.measures.lens import distort_terms

    cam = _camera(tuple(float(d) for d in dist))
    xy = RNG.uniform(-0.5, 0.5, (50, 2))
    u, v, *D = distort_terms(cam, xy[:, 0], xy[:, 1])
    np.testing.assert_allclose(np.stack([u, v], axis=-1), cam.distort_normalized(xy), rtol=1e-13)
    ref = cam.distortion_jacobian(xy)
    for k, d in enumerate(D):
        np.testing.assert_allclose(np.broadcast_to(d, (50,)), ref[:, k // 2, k % 2], rtol=1e-12, atol=1e-9)
