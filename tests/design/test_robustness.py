"""Robustness sampling (cadfeat.design.robustness) against independent evaluations.

The camera mounting error is checked against a Problem built anew on the displaced trajectory
(``T_task_cam @ ΔT``, its velocity screws differentiated numerically from the poses by ``Trajectory``), the
manufacturing tolerance against ``Problem.features_objectives`` of the displaced holes one by one."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from study_helpers import plate_study

from cadfeat.design.problem import Problem
from cadfeat.design.robustness import camera_objectives, robustness
from cadfeat.poses import rotvec_matrix
from cadfeat.study.schema import load_study
from cadfeat.study.setup import setup_study
from cadfeat.trajectory import Trajectory

pytestmark = pytest.mark.numerics  # run again under another BLAS kernel (Makefile: test)

STUDY = plate_study("robust_plate")


@pytest.fixture(scope="module")
def setup():
    return setup_study(load_study(copy.deepcopy(STUDY)))


def test_camera_mount_error_equals_a_rebuilt_problem(setup):
    p = setup.problem
    c, a, r = (np.asarray(v, float) for v in setup.model.features(setup.space.x0))
    dT = np.eye(4)
    dT[:3, :3] = rotvec_matrix(np.radians([[0.8, -0.5, 1.0]]))[0]
    dT[:3, 3] = [1.5, -2.0, 0.7]
    G = camera_objectives(p, c, a, r, dT[None])[0]
    traj = Trajectory(np.asarray(setup.trajectory.T_task_cam) @ dT, setup.trajectory.times_s)
    ref = Problem(p.space, p.model, p.camera, traj, p.T_task_part, p.objective_config, p.constraint_config,
                  p.fixed_mask, normaliser=p.normaliser).features_objectives(c, a, r)
    np.testing.assert_allclose(G, ref, rtol=2e-3, atol=1e-9)
    G0 = camera_objectives(p, c, a, r, np.eye(4)[None])[0]  # no error: the nominal objectives
    np.testing.assert_allclose(G0, p.features_objectives(c, a, r), rtol=1e-9)


def test_manufacturing_samples_and_razor_edge(setup):
    p = setup.problem
    c, a, r = (np.asarray(v, float) for v in setup.model.features(setup.space.x0))
    changed = np.asarray(setup.movable_mask, bool)
    zero = robustness(p, c, a, r, changed, position_tol_mm=0.0, size_steps=0, camera_position_mm=0.0,
                      camera_angle_deg=0.0, samples=8)
    for block in ("manufacturing", "camera"):
        for name in p.names:
            s = zero[block][name]
            assert s["min"] == pytest.approx(s["nominal"], rel=1e-9) == s["p05"]
    res = robustness(p, c, a, r, changed, position_tol_mm=0.3, size_steps=1, sizes=(3.4, 4.5, 5.5), samples=16,
                     seed=3)
    # the same draws, evaluated design by design with the single-design objective
    rng = np.random.default_rng(3)
    du = rng.uniform(-1, 1, (16, len(r), 2)) * 0.3 * changed[None, :, None]
    steps = rng.integers(-1, 2, (16, len(r))) * changed[None]
    table = np.array([3.4, 4.5, 5.5])
    k0 = np.argmin(np.abs(table[None] - 2 * r[:, None]), axis=1)
    helper = np.eye(3)[np.argmin(np.abs(a), axis=1)]
    u = helper - np.sum(helper * a, axis=1, keepdims=True) * a
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(a, u)
    G = []
    for s in range(16):
        cs = c + du[s, :, :1] * u + du[s, :, 1:] * v
        rs = np.where(changed, table[np.clip(k0 + steps[s], 0, 2)] / 2, r)
        G.append(p.features_objectives(cs, a, rs))
    G = np.array(G)
    for k, name in enumerate(p.names):
        assert res["manufacturing"][name]["min"] == pytest.approx(G[:, k].min(), rel=1e-9)
        assert res["manufacturing"][name]["p05"] == pytest.approx(np.percentile(G[:, k], 5), rel=1e-9)
    nominal = res["manufacturing"]["combined"]["nominal"]
    # a gain that any perturbation loses more than half of is a razor edge; a tiny claimed gain is not
    assert robustness(p, c, a, r, changed, samples=16, sizes=(3.4, 4.5, 5.5),
                      combined_before=nominal - 1e-12)["razor_edge"]
    assert robustness(p, c, a, r, changed, samples=16, sizes=(3.4, 4.5, 5.5),
                      combined_before=nominal - 1e3)["razor_edge"] == []
