"""Batched evaluations within a memory budget (cadfeat.design.memory, issue 16 item 4).

Chunked evaluation is checked against one unchunked call of the same draws (the draws are independent, so the
numbers must be equal); the refusal at set-up is checked on the largest trajectory the study limits allow."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from study_helpers import plate_study

from cadfeat.design import memory
from cadfeat.design.memory import MemoryBudgetError, check_fits, chunked, design_bytes
from cadfeat.design.problem import Problem
from cadfeat.design.robustness import camera_objectives, robustness
from cadfeat.study.schema import LIMITS, load_study
from cadfeat.study.setup import setup_study

STUDY = plate_study("memory_plate")


@pytest.fixture(scope="module")
def setup():
    return setup_study(load_study(copy.deepcopy(STUDY)))


def _design(setup):
    return tuple(np.asarray(v, float) for v in setup.model.features(setup.space.x0))


def test_chunked_robustness_equals_one_batch(setup, monkeypatch):
    """Camera draws (sharing the nominal depth maps through a view) and manufacturing draws in chunks of 3: the
    same numbers as all draws in one batch."""
    p = setup.problem
    c, a, r = _design(setup)
    changed = np.ones(len(r), bool)
    whole = robustness(p, c, a, r, changed, samples=10, seed=3)
    per_draw = design_bytes(len(p.screws), len(r))
    calls = []
    real = memory.chunked

    def spy(fn, n, bytes_per_item, what):
        calls.append((n, memory.chunk_size(bytes_per_item, what)))
        return real(fn, n, bytes_per_item, what)

    monkeypatch.setattr(memory, "MEMORY_BUDGET_BYTES", 3 * per_draw)
    monkeypatch.setattr(memory, "chunked", spy)
    parts = robustness(p, c, a, r, changed, samples=10, seed=3)
    assert any(n == 10 and step == 3 for n, step in calls), calls  # the camera draws really were cut in 4 chunks
    for key in ("manufacturing", "camera"):
        for name, block in whole[key].items():
            for stat, value in block.items():
                assert parts[key][name][stat] == pytest.approx(value, rel=1e-12, abs=1e-12), (key, name, stat)


def test_chunked_batch_objectives_equal_one_batch(setup, monkeypatch):
    p = setup.problem
    X = p.space.from_unit(np.random.default_rng(0).uniform(size=(7, p.space.size)))
    c, a, r = p.model.features_batch(X)
    whole = p.batch_objectives(c, a, r)
    monkeypatch.setattr(memory, "MEMORY_BUDGET_BYTES", 2 * design_bytes(len(p.screws), r.shape[1]))
    np.testing.assert_allclose(p.batch_objectives(c, a, r), whole, rtol=1e-12, atol=1e-12)


def test_chunked_concatenates_tuples_and_refuses_an_item_too_large(monkeypatch):
    monkeypatch.setattr(memory, "MEMORY_BUDGET_BYTES", 100)
    out = chunked(lambda sl: (np.arange(10)[sl], -np.arange(10)[sl]), 10, 30, "test")
    np.testing.assert_array_equal(out[0], np.arange(10))
    np.testing.assert_array_equal(out[1], -np.arange(10))
    with pytest.raises(MemoryBudgetError, match="memory budget"):
        chunked(lambda sl: np.zeros(1), 10, 101, "test")


def test_environment_overrides_the_budget(monkeypatch):
    monkeypatch.setenv("CADFEAT_MEMORY_BUDGET_BYTES", "2048")
    assert memory.budget_bytes() == 2048
    with pytest.raises(MemoryBudgetError):
        check_fits(10, occlusion=True)  # 10 depth maps of 128² float64 cells: 1.25 MiB > 2 kiB


def test_the_largest_trajectory_is_refused_before_any_work(tmp_path, monkeypatch):
    """The most samples the study limits allow (with occlusion: 100,000 depth maps ≈ 12 GiB): one clear line
    before any CAD work (the set-up is never reached) and nothing written."""
    import cadfeat.study.setup as setup_mod
    from cadfeat.study.run import run_study

    def no_setup(*args, **kwargs):
        raise AssertionError("set-up reached")

    monkeypatch.setattr(setup_mod, "setup_script", no_setup)
    monkeypatch.setattr(setup_mod, "setup_study", no_setup)
    study = copy.deepcopy(STUDY)
    study["trajectory"]["n"] = LIMITS["trajectory_samples"]
    with pytest.raises(MemoryBudgetError) as info:
        run_study(study, tmp_path / "out", quiet=True)
    text = str(info.value)
    assert "\n" not in text and "100,000" in text and "memory budget" in text and "at most 8,160" in text
    assert not (tmp_path / "out").exists()


def test_the_largest_trajectory_without_occlusion_is_evaluated_in_chunks(setup, monkeypatch):
    """100,000 poses without occlusion fit one design at a time: the camera draws run one per chunk (budget cut
    to one draw) and give finite values; the undisplaced draw equals a direct evaluation."""
    n = LIMITS["trajectory_samples"]
    study = copy.deepcopy(STUDY)
    study["trajectory"]["n"] = n
    traj = load_study(study).trajectory.build()
    p0 = setup.problem
    p = Problem(p0.space, p0.model, p0.camera, traj, p0.T_task_part,
                p0.objective_config.replace(occlusion=False) if hasattr(p0.objective_config, "occlusion")
                else p0.objective_config, p0.constraint_config, p0.fixed_mask, normaliser=p0.normaliser,
                feature_mask=p0.feature_mask)
    c, a, r = _design(setup)
    monkeypatch.setattr(memory, "MEMORY_BUDGET_BYTES", design_bytes(n, len(r)))  # one draw per chunk
    dT = np.tile(np.eye(4), (2, 1, 1))
    dT[1, :3, 3] = (0.5, -0.5, 1.0)
    G = camera_objectives(p, c, a, r, dT)
    assert G.shape == (2, len(p.names)) and np.all(np.isfinite(G))
    np.testing.assert_allclose(G[0], p.features_objectives(c, a, r), rtol=1e-9)  # the undisplaced camera
