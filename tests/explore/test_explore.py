"""The explorer's pieces without a browser: the exact ray cache, the GLB export, never overwriting.

References: trimesh's own ray queries and ``measures.visibility.occluded`` on the bare mesh (the cache must give
the same booleans and hit points), the STL that ``cadfeat.cad.export.export_stl`` writes of the same solid
(the GLB re-imported with trimesh must be the same surface), the part's own hole names.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cadfeat.explore.raycache import CachedRayMesh
from cadfeat.explore.session import new_path

DATA = Path(__file__).parents[1] / "data" / "cqgi"


def _plate_mesh():
    from cadfeat.cad.export import mesh_from_shape
    from cadfeat.cad.parts import load_part

    part = load_part(DATA / "Ex003_Pillow_Block_With_Counterbored_Holes.py")
    return part, mesh_from_shape(part.build(), tolerance=0.05)


def test_ray_cache_is_exact():
    """Occlusion through the cache = occlusion on the bare mesh, for a first call, a repeated call and a call in
    which only some holes moved (those rays are traced again, the others come from the cache)."""
    from cadfeat.measures.visibility import occluded

    _, mesh = _plate_mesh()
    rng = np.random.default_rng(0)
    cams = np.column_stack([rng.uniform(-80, 80, 30), rng.uniform(-80, 80, 30), rng.uniform(-40, 200, 30)])
    centres = np.array([[-34, -44, 5], [34, 44, 5], [0, 0, 5], [0, 0, -5], [40, 0, 0]], float)
    axes = np.array([[0, 0, 1], [0, 0, 1], [0, 0, 1], [0, 0, -1], [1, 0, 0]], float)
    cached = CachedRayMesh(mesh)
    first = occluded(cached, cams, centres, axes)
    np.testing.assert_array_equal(first, occluded(mesh, cams, centres, axes))
    assert first.any() and not first.all()
    np.testing.assert_array_equal(occluded(cached, cams, centres, axes), first)
    assert cached.hits == first.size
    moved = centres.copy()
    moved[0] += [3.0, -2.0, 0.0]
    np.testing.assert_array_equal(occluded(cached, cams, moved, axes), occluded(mesh, cams, moved, axes))
    assert cached.misses == first.size + len(cams)  # only the moved hole's rays were traced again
    o, d = rng.normal(size=(50, 3)) * 30 + [0, 0, 100], rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    want = mesh.ray.intersects_location(o, d, multiple_hits=True)
    got = CachedRayMesh(mesh).intersects_location(o, d, multiple_hits=True)
    key = lambda r: sorted(zip(r[1].tolist(), r[2].tolist(), map(tuple, np.round(r[0], 9)), strict=True))  # noqa: E731
    assert key(got) == key(want)


def test_a_mesh_given_a_ray_cache_answers_as_the_bare_mesh():
    """``cache_rays`` (the study's occlusion meshes): the same occlusion as a freshly built mesh without the cache,
    a repeated query answered from the cache, and the intersector's other queries (``contains``) unchanged."""
    from cadfeat.measures.raycache import CachedRayMesh, cache_rays
    from cadfeat.measures.visibility import occluded

    part, mesh = _plate_mesh()
    _, bare = _plate_mesh()
    assert cache_rays(mesh) is mesh and cache_rays(mesh).ray is mesh.ray and isinstance(mesh.ray, CachedRayMesh)
    rng = np.random.default_rng(1)
    cams = np.column_stack([rng.uniform(-80, 80, 20), rng.uniform(-80, 80, 20), rng.uniform(-40, 200, 20)])
    centres = np.array([[-34, -44, 5], [34, 44, 5], [0, 0, 5], [40, 0, 0]], float)
    axes = np.array([[0, 0, 1], [0, 0, 1], [0, 0, 1], [1, 0, 0]], float)
    want = occluded(bare, cams, centres, axes)
    assert want.any() and not want.all()
    np.testing.assert_array_equal(occluded(mesh, cams, centres, axes), want)
    np.testing.assert_array_equal(occluded(mesh, cams, centres, axes), want)
    assert mesh.ray.hits == want.size and mesh.ray.misses == want.size
    points = rng.uniform(-60, 60, (50, 3))
    np.testing.assert_array_equal(mesh.contains(points), bare.contains(points))


def test_glb_nodes_are_hole_names_and_geometry_is_the_stl(tmp_path):
    import trimesh

    from cadfeat.cad.export import export_stl
    from cadfeat.cad.gltf import MM_TO_M, export_glb

    part, _ = _plate_mesh()
    shape, holes = part.build(cbore_inset=18.0), part.holes(cbore_inset=18.0)
    export_glb(shape, holes, tmp_path / "p.glb")
    export_stl(shape, tmp_path / "p.stl")
    scene = trimesh.load(tmp_path / "p.glb")
    nodes = set(scene.graph.nodes_geometry)
    assert nodes == {h.name for h in holes} | {"part"}
    stl = trimesh.load(tmp_path / "p.stl")
    glb = trimesh.util.concatenate([scene.geometry[scene.graph[n][1]] for n in nodes])
    assert len(glb.faces) == len(stl.faces)
    np.testing.assert_allclose(glb.bounds / MM_TO_M, stl.bounds, atol=1e-4)
    assert glb.area / MM_TO_M**2 == pytest.approx(stl.area, rel=1e-6)
    glb_m = glb.copy()
    glb_m.merge_vertices(digits_vertex=6)
    assert glb_m.is_watertight and glb_m.volume / MM_TO_M**3 == pytest.approx(stl.volume, rel=1e-6)
    for h in holes:  # each hole's node sits in that hole: within its rim radius of its axis
        mesh = scene.geometry[scene.graph[h.name][1]]
        d = mesh.vertices / MM_TO_M - h.centre
        radial = np.linalg.norm(d - np.outer(d @ h.axis, h.axis), axis=1)
        assert radial.max() <= h.radius_mm + 1e-3


def test_new_path_never_reuses_a_name(tmp_path):
    (tmp_path / "s-start-1.toml").write_text("mine")
    path = new_path(tmp_path, "s-start", ".toml")
    assert path.name == "s-start-2.toml"
    assert (tmp_path / "s-start-1.toml").read_text() == "mine"


def test_busy_port_is_refused_before_any_work(capsys):
    """The port is checked before the study is loaded: a busy port fails at once, naming the address."""
    import socket

    from cadfeat.cli import main

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["explore", str(DATA / "ex003_study.toml"), "--port", str(port), "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert f"cannot listen on 127.0.0.1:{port}" in err and "loading" not in err


def _get(url: str) -> tuple[int, bytes]:
    import urllib.error
    import urllib.request

    try:
        with urllib.request.urlopen(url, timeout=30) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read()


def _slow_study(tmp_path: Path, build: str) -> Path:
    """The study tests' plate study, its part script's ``build`` preceded by ``build`` (a statement)."""
    from study_helpers import PLATE, study

    path = study(tmp_path, design={"parameters": {"x0": {"lower": -15, "upper": -5}}})
    (tmp_path / "study_plate.py").write_text(PLATE.read_text().replace(
        "    import cadquery as cq\n", f"    import cadquery as cq\n    {build}\n", 1))
    return path


def test_the_page_is_served_at_once_and_shows_the_set_up(tmp_path):
    """While the study is set up (its part takes 0.4 s a build), the server answers: the page, the set-up's status
    (the phase, the time so far), 503 for what needs the study; once ready, the scene and the numbers."""
    import json
    import urllib.error
    import urllib.request

    from cadfeat.explore.loader import SessionLoader
    from cadfeat.explore.server import serve

    loader = SessionLoader(_slow_study(tmp_path, "import time; time.sleep(0.4)"), cache=False)
    server = serve(loader.start(), 0)
    try:
        code, page = _get(server.url)
        assert code == 200 and b"explore.js" in page
        status = json.loads(_get(server.url + "api/status")[1])
        assert status["state"] == "setting-up" and status["study"] == "plate" and status["phase"], status
        code, body = _get(server.url + "api/scene")
        assert code == 503 and json.loads(body)["status"]["state"] == "setting-up"
        req = urllib.request.Request(server.url + "api/evaluate", b"{}", {"Content-Type": "application/json"})
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(req, timeout=30)
        assert err.value.code == 503 and "still being set up" in json.loads(err.value.read())["error"]
        assert loader.done.wait(300)
        status = json.loads(_get(server.url + "api/status")[1])
        assert status["state"] == "ready" and status["ready_s"] > 0.4 and status["cache"] == "off", status
        code, body = _get(server.url + "api/scene")
        assert code == 200 and [v["name"] for v in json.loads(body)["variables"]] == ["x0"]
    finally:
        server.stop()


def test_a_set_up_that_fails_is_shown(tmp_path):
    import json

    from cadfeat.explore.loader import SessionLoader
    from cadfeat.explore.server import serve

    loader = SessionLoader(_slow_study(tmp_path, "raise RuntimeError('no such tool')"), cache=False)
    server = serve(loader.start(), 0)
    try:
        assert loader.done.wait(300)
        status = json.loads(_get(server.url + "api/status")[1])
        assert status["state"] == "failed" and "no such tool" in status["error"], status
        code, body = _get(server.url + "api/scene")
        assert code == 503 and "set-up failed" in json.loads(body)["error"]
    finally:
        server.stop()
