"""The study set-up cache (``cadfeat.study.setup_cache``, issue 32 item 6).

References: the set-up made without the cache (every array compared exactly — the cached one must be the same
numbers, not close ones), the study's own measures and objectives of both, the part's CAD rebuild at a design
(loaded on demand from a cached set-up), and ``tools/compare_results.py`` on two runs' results.json.
"""

from __future__ import annotations

import copy
import dataclasses
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from study_helpers import compare_results_tool, study

from cadfeat.errors import CadfeatError
from cadfeat.study.pipeline import measure_holes
from cadfeat.study.schema import load_study
from cadfeat.study.setup import load_scene
from cadfeat.study.setup_cache import (
    MARKER,
    CachedSetup,
    CacheWarning,
    SetupCache,
    cached_setup,
    input_key,
    open_cache,
    part_files,
    save,
)

ROOT = Path(__file__).resolve().parents[2]
ONE_VARIABLE = {"parameters": {"x0": {"lower": -15, "upper": -5}, "count": {}}}


def _study(tmp_path: Path, **changes: dict) -> Path:
    """The plate study of ``study_helpers.study`` (x0 and the integer count vary; occlusion on)."""
    return study(tmp_path, design=ONE_VARIABLE, **changes)


def _set_up(path: Path, cache: SetupCache | None):
    """The set-up as ``cadfeat evaluate`` / ``explore`` make it: through the cache, normaliser built, then kept."""
    config = load_study(path)
    setup = cached_setup(config, cache=cache)
    setup.problem.normaliser  # noqa: B018 - built (what the consumers do before ``save``)
    save(setup)
    return setup


def _same_measures(a, b) -> None:
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        else:
            assert x == y, f.name


def test_a_second_set_up_is_a_hit_with_the_same_numbers(tmp_path):
    path = _study(tmp_path)
    cache = open_cache(True, tmp_path / "cache")
    fresh = _set_up(path, cache)
    assert fresh.cache_entry is not None and not fresh.cache_entry.hit
    assert len(cache.listing()) == 1
    hit = _set_up(path, cache)
    assert hit.cache_entry.hit and isinstance(hit, CachedSetup)
    reference = _set_up(path, None)  # no cache at all
    assert reference.cache_entry is None

    for s in (hit, reference):
        assert s.holes0 == fresh.holes0 and s.hole_names == fresh.hole_names
        for name in ("fixed_mask", "movable_mask"):
            np.testing.assert_array_equal(getattr(s, name), getattr(fresh, name))
        assert s.space.variables == fresh.space.variables and s.linear == fresh.linear
        np.testing.assert_array_equal(s.space.x0, fresh.space.x0)
        assert s.problem.normaliser.to_dict() == fresh.problem.normaliser.to_dict()
        mesh, mesh0 = s.problem.occlusion_mesh, fresh.problem.occlusion_mesh
        np.testing.assert_array_equal(mesh.vertices, mesh0.vertices)
        np.testing.assert_array_equal(mesh.faces, mesh0.faces)
    X = np.random.default_rng(0).uniform(fresh.space.lower, fresh.space.upper, (9, fresh.space.size))
    G0, C0 = fresh.problem.evaluate_batch(X)
    for s in (hit, reference):
        for got, want in zip(s.model.features_batch(X), fresh.model.features_batch(X), strict=True):
            np.testing.assert_array_equal(got, want)
        G, C = s.problem.evaluate_batch(X)
        np.testing.assert_array_equal(G, G0)
        np.testing.assert_array_equal(C, C0)
        np.testing.assert_array_equal(s.problem.normalised(G), fresh.problem.normalised(G0))
        # the exact ray test against the cached mesh: every measure the same
        _same_measures(measure_holes(s, s.holes0), measure_holes(fresh, fresh.holes0))
        assert s.values(X[0]) == fresh.values(X[0])
    # the CAD side, loaded on demand: the original solid (from the entry) and a rebuild at a design
    assert hit.shape0.Volume() == fresh.shape0.Volume()
    assert hit.rebuild_holes(hit.rebuild_shape(X[3])) == fresh.rebuild_holes(fresh.rebuild_shape(X[3]))


def test_an_edited_part_or_study_misses(tmp_path):
    path = _study(tmp_path)
    cache = open_cache(True, tmp_path / "cache")
    first = _set_up(path, cache)
    key = first.cache_entry.key
    config = load_study(path)
    assert input_key(config, load_scene(config)) == key
    # the study file edited in place: a kept requirement, the camera, the trajectory; then as it was
    for section, changes in (("constraints", {"edge_distance_mm": 3.0}), ("camera", {"focus_distance_mm": 210.0}),
                             ("trajectory", {"n": 11})):
        edited = load_study(_study(tmp_path, **{section: changes}))
        assert input_key(edited, load_scene(edited)) != key, section
    config = load_study(_study(tmp_path))
    assert input_key(config, load_scene(config)) == key
    # the part script: one byte more is a miss (a fresh set-up, kept beside the first), the original a hit again
    part = tmp_path / "study_plate.py"
    original = part.read_bytes()
    part.write_bytes(original + b"\n# edited\n")
    edited = _set_up(path, cache)
    assert not edited.cache_entry.hit and edited.cache_entry.key != key
    assert len(cache.listing()) == 2
    part.write_bytes(original)
    again = _set_up(path, cache)
    assert again.cache_entry.hit and again.cache_entry.key == key
    # another integer combination is another set-up
    assert input_key(config, load_scene(config), {"count": 2}) != key


def test_a_module_beside_the_part_script_is_in_the_key(tmp_path):
    (tmp_path / "helper.py").write_text("PITCH = 10.0\n")
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "__init__.py").write_text("")
    (tmp_path / "pkg" / "holes.py").write_text("R = 2\n")
    script = tmp_path / "part.py"
    script.write_text("import math\nimport helper\nfrom pkg.holes import R\n\ndef build():\n    pass\n")
    files = part_files(script)
    assert set(files) == {str(script), str(tmp_path / "helper.py"), str(tmp_path / "pkg" / "__init__.py"),
                          str(tmp_path / "pkg" / "holes.py")}
    before = files[str(tmp_path / "helper.py")]
    (tmp_path / "helper.py").write_text("PITCH = 12.0\n")
    assert part_files(script)[str(tmp_path / "helper.py")] != before


def test_a_damaged_entry_is_ignored_with_a_warning_and_replaced(tmp_path):
    path = _study(tmp_path)
    cache = open_cache(True, tmp_path / "cache")
    key = _set_up(path, cache).cache_entry.key
    entry = cache.path(key)
    good = entry.read_bytes()
    for damage in (b"not a pickle", good[: len(good) // 2],
                   pickle.dumps({"format": -1, "key": key, "products": {}})):
        entry.write_bytes(damage)
        with pytest.warns(CacheWarning, match="damaged"):
            setup = _set_up(path, cache)
        assert not setup.cache_entry.hit  # set up again ...
        assert _set_up(path, cache).cache_entry.hit  # ... and the entry replaced by a good one
    assert [p.name for p in cache.entries.iterdir()] == [entry.name]  # no temporary files left


def test_a_folder_cadfeat_did_not_create_is_left_alone(tmp_path, monkeypatch):
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.warns(CacheWarning, match="did not write"):
        assert open_cache(True, foreign) is None
    assert sorted(p.name for p in foreign.iterdir()) == ["notes.txt"]
    with pytest.raises(CadfeatError, match="not a cadfeat set-up cache"):
        SetupCache(foreign).clear()
    # the default folder and the switches
    monkeypatch.setenv("CADFEAT_CACHE_DIR", str(tmp_path / "c"))
    monkeypatch.setenv("CADFEAT_CACHE", "off")
    assert open_cache() is None and open_cache(True) is not None
    assert (tmp_path / "c" / MARKER).is_file() and (tmp_path / "c" / "CACHEDIR.TAG").is_file()
    monkeypatch.setenv("CADFEAT_CACHE", "on")
    assert open_cache(False) is None and open_cache().root == tmp_path / "c"


def test_evaluate_and_run_on_unchanged_inputs_read_the_cache(tmp_path, monkeypatch):
    """``cadfeat evaluate`` keeps the set-up; ``run`` then reads it (the same key) and gives the results.json of a
    run without the cache (tools/compare_results.py: identical apart from times and versions)."""
    from cadfeat.study import run as study_run
    from cadfeat.study.run import evaluate_study, run_study

    monkeypatch.setattr(study_run, "_report", lambda *a, **k: None)  # (the report is tested elsewhere)
    monkeypatch.setenv("CADFEAT_CACHE_DIR", str(tmp_path / "cache"))
    path = study(tmp_path, design={"parameters": {"x0": {"lower": -15, "upper": -5}}})
    first = evaluate_study(path, cache=True)
    cache = SetupCache(tmp_path / "cache")
    assert len(cache.listing()) == 1
    seen = []
    real = cached_setup

    def spy(*args, **kwargs):
        setup = real(*args, **kwargs)
        seen.append(None if setup.cache_entry is None else setup.cache_entry.hit)
        return setup

    monkeypatch.setattr("cadfeat.study.run.cached_setup", spy)
    monkeypatch.setattr("cadfeat.study.pipeline.cached_setup", spy)
    assert compare_results_tool().compare(evaluate_study(path, cache=True), first) == []
    cached = run_study(path, tmp_path / "cached", quiet=True, cache=True)
    assert seen == [True, True]
    plain = run_study(copy.deepcopy(path), tmp_path / "plain", quiet=True, cache=False)
    assert seen == [True, True, None]  # (no cache)
    assert compare_results_tool().compare_files(tmp_path / "cached", tmp_path / "plain") == []
    assert cached.results["objectives"]["after"] == plain.results["objectives"]["after"]


def test_a_warm_set_up_imports_no_cad_kernel(tmp_path):
    """Read from the cache, the explorer's session needs neither CadQuery nor a part build: it is imported only
    when a rebuild or an export asks for the CAD model."""
    path = _study(tmp_path)
    _set_up(path, open_cache(True, tmp_path / "cache"))
    code = ("import sys\nfrom cadfeat.explore.session import ExploreSession\n"
            f"s = ExploreSession({str(path)!r}, cache=True)\ns.scene()\n"
            "print(s.status.cache, 'cadquery' in sys.modules, 'OCP' in sys.modules, 'mitsuba' in sys.modules)\n")
    env = {**os.environ, "CADFEAT_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["hit", "False", "False", "False"]


def test_the_glare_maps_are_kept(tmp_path):
    """g_POSE in a metal part: the set-up renders the part's glare maps (Mitsuba, one per pose); the cache keeps
    them, so a hit predicts the same pose error without rendering (and without the renderer)."""
    path = _study(tmp_path, objective={"measures": ["pose"]})
    cache = open_cache(True, tmp_path / "cache")
    fresh = _set_up(path, cache)
    if fresh.problem.glare is None:
        pytest.skip("the study's cell renders no glare maps")
    hit = _set_up(path, cache)
    assert hit.cache_entry.hit
    for name in ("grey", "holes_centre", "holes_radius"):
        np.testing.assert_array_equal(getattr(hit.problem.glare, name), getattr(fresh.problem.glare, name))
    assert hit.problem.glare.camera == fresh.problem.glare.camera
    X = np.random.default_rng(1).uniform(fresh.space.lower, fresh.space.upper, (5, fresh.space.size))
    for got, want in zip(hit.problem.evaluate_batch(X), fresh.problem.evaluate_batch(X), strict=True):
        np.testing.assert_array_equal(got, want)
