"""Part scripts and the parts library.

References: each part script's ``expected_holes(**params)`` — the analytic hole centres / axes / radii
written from the part's drawing (the docstring), independently of its build code — compared with the
holes EXTRACTED from the built B-rep at 1e-9 mm; hand-written bad scripts for the error messages.
"""

from __future__ import annotations

import textwrap
import zlib
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from cadfeat.cad.features import holes_to_arrays
from cadfeat.cad.parts import PARTS_DIR, PartBuildError, build_shape, find_parts, load_part
from cadfeat.errors import CadfeatError

TOL_MM = 1e-9
PART_PATHS = find_parts(PARTS_DIR)


def parameter_sets(part) -> list[dict]:
    """Defaults, and every parameter at 25 % and at 75 % of its range (integers rounded)."""
    sets = [part.defaults()]
    for frac in (0.25, 0.75):
        values = {}
        for name, p in part.parameters.items():
            v = p.lower + frac * (p.upper - p.lower)
            values[name] = int(round(v)) if p.is_int else v
        sets.append(values)
    return sets


def assert_holes_match(holes, expected, tol=TOL_MM):
    """Extracted holes equal the analytic ones (optimal pairing by centre distance)."""
    c, a, r = holes_to_arrays(holes)
    ec = np.array([e["centre"] for e in expected], dtype=float)
    ea = np.array([e["axis"] for e in expected], dtype=float)
    er = np.array([e["radius_mm"] for e in expected], dtype=float)
    assert len(holes) == len(expected), f"{len(holes)} holes extracted, {len(expected)} expected"
    d = np.linalg.norm(c[:, None, :] - ec[None, :, :], axis=-1)
    rows, cols = linear_sum_assignment(d)
    assert d[rows, cols].max() <= tol, f"centre error {d[rows, cols].max():.3g} mm"
    assert np.abs(r[rows] - er[cols]).max() <= tol
    assert np.abs(a[rows] - ea[cols] / np.linalg.norm(ea[cols], axis=1, keepdims=True)).max() <= 1e-12
    for i, j in zip(rows, cols, strict=True):
        assert holes[i].kind == expected[j].get("kind", holes[i].kind)


def test_library_is_not_empty():
    assert len(PART_PATHS) >= 8


@pytest.mark.parametrize("path", PART_PATHS, ids=[p.stem for p in PART_PATHS])
def test_part_holes_equal_drawing(path):
    part = load_part(path)
    assert part.description and part.parameters
    assert part.module.expected_holes is not None, "every library part documents its holes"
    for params in parameter_sets(part):
        assert_holes_match(part.holes(**params), part.expected_holes(**params))


def _separated(expected, gap_mm=0.2) -> bool:
    """Whether no two analytic holes with parallel axes come closer than ``gap_mm`` (rim to rim)."""
    c = np.array([e["centre"] for e in expected], dtype=float)
    a = np.array([e["axis"] for e in expected], dtype=float)
    r = np.array([e["radius_mm"] for e in expected], dtype=float)
    d = np.linalg.norm(c[:, None] - c[None], axis=-1)
    parallel = np.abs(a @ a.T) > 1 - 1e-9
    close = parallel & (d < r[:, None] + r[None] + gap_mm)
    return not np.any(np.triu(close, 1))


@pytest.mark.parametrize("path", PART_PATHS, ids=[p.stem for p in PART_PATHS])
def test_part_holes_random_designs(path):
    """Random designs within the bounds (seeded): every design whose holes do not overlap (a feasible
    layout; overlapping ones are for the ligament constraint to reject) is extracted exactly."""
    part = load_part(path)
    rng = np.random.default_rng(zlib.crc32(path.stem.encode()))
    checked = 0
    for _ in range(4):
        params = {n: int(rng.integers(p.lower, p.upper + 1)) if p.is_int else float(rng.uniform(p.lower, p.upper))
                  for n, p in part.parameters.items()}
        expected = part.expected_holes(**params)
        if _separated(expected):
            assert_holes_match(part.holes(**params), expected)
            checked += 1
    assert checked


@pytest.mark.parametrize("path", PART_PATHS, ids=[p.stem for p in PART_PATHS])
def test_part_metadata(path):
    part = load_part(path)
    text = path.read_text()
    assert 'if "show_object" in globals()' in text  # runs unchanged in cq-editor
    assert part.view_direction is not None and np.isclose(np.linalg.norm(part.view_direction), 1.0)
    assert part.fixed_holes, "FIXED_HOLES documents the functional holes (or says none)"
    for p in part.parameters.values():
        assert p.description and p.lower <= p.default <= p.upper


def test_scripts_run_unchanged_in_cq_editor():
    """Executed as cq-editor does (a global ``show_object``), a script shows exactly one solid."""
    import runpy

    import cadquery as cq

    for path in PART_PATHS:
        shown = []
        runpy.run_path(str(path), init_globals={"show_object": shown.append})
        assert len(shown) == 1 and isinstance(shown[0], cq.Workplane), path.name
        assert len(shown[0].val().Solids()) == 1


@pytest.mark.parametrize("name, n_fixed", [("industrial_plate", 7), ("nema17_mount", 5), ("l_bracket", 2),
                                           ("pipe_flange_dn50", 5), ("brake_disc_hub", 6), ("thesis_hub", 1),
                                           ("thesis_array_2d", 0)])
def test_fixed_mask_marks_the_documented_functional_holes(name, n_fixed):
    part = load_part(PARTS_DIR / f"{name}.py")
    params = parameter_sets(part)[1]
    holes = part.holes(**params)
    mask = part.fixed_mask(holes, params)
    assert mask.sum() == n_fixed
    from cadfeat.cad.design_map import design_map

    free = [n for n, p in part.parameters.items() if not p.is_int]
    if name == "pipe_flange_dn50":  # no parameter moves a fixed hole, every other hole is moved by one
        dm = design_map(part, free, at=params)
        moved = sorted({i for v in dm.moved_by.values() for i in v})
        assert not mask[moved].any()
        assert set(moved) | set(np.flatnonzero(mask)) == set(range(len(holes)))


def test_build_returns_one_solid_and_validates():
    part = load_part(PARTS_DIR / "thesis_single_hole.py")
    solid = part.build(radius_mm=2.0)
    assert solid.isValid() and len(solid.Solids()) == 1
    with pytest.raises(CadfeatError, match=r"unknown parameter\(s\) 'radius'.*allowed: radius_mm, hole_x_mm"):
        part.build(radius=2.0)
    with pytest.raises(CadfeatError, match=r"'radius_mm' = 9 is out of bounds; allowed: a number in \[1, 6\] mm"):
        part.build(radius_mm=9)
    with pytest.raises(CadfeatError, match="not a number"):
        part.build(radius_mm="3")
    hub = load_part(PARTS_DIR / "thesis_hub.py")
    assert hub.parameters["hole_count"].is_int
    with pytest.raises(CadfeatError, match="'hole_count' = 4.5 is not an integer"):
        hub.build(hole_count=4.5)
    assert len(hub.holes(hole_count=4.0)) == 5


# ------------------------------------------------------------------------------------ bad scripts
GOOD_HEAD = '''
import cadquery as cq
PARAMETERS = {"size_mm": {"default": 10.0, "bounds": (5.0, 20.0), "unit": "mm", "description": "edge"}}
'''


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


@pytest.mark.parametrize("name, body, match", [
    ("syntax.py", "x = (1,\ndef build(:\n", r"syntax\.py:\d+: syntax error"),
    ("nobuild.py", GOOD_HEAD, r"nobuild\.py: no build\(\*\*params\) function"),
    ("noparams.py", "def build():\n    return None\n", r"noparams\.py: no PARAMETERS dict"),
    ("badkey.py", 'PARAMETERS = {"a": {"default": 1.0, "bounds": (0, 2), "units": "mm"}}\ndef build(a): pass\n',
     r"badkey\.py: PARAMETERS\['a'\] has unknown key\(s\) 'units'; allowed: default, bounds, unit, description"),
    ("nobounds.py", 'PARAMETERS = {"a": {"default": 1.0}}\ndef build(a): pass\n',
     r"PARAMETERS\['a'\] lacks 'bounds'"),
    ("outside.py", 'PARAMETERS = {"a": {"default": 3.0, "bounds": (0, 2)}}\ndef build(a): pass\n',
     r"PARAMETERS\['a'\]: default 3 is outside bounds \[0, 2\]"),
    ("signature.py", 'PARAMETERS = {"a": {"default": 1.0, "bounds": (0, 2)}}\ndef build(b): pass\n',
     r"signature\.py: build\(b\) does not match PARAMETERS \(a\): not accepted: a; required but not in "
     r"PARAMETERS: b"),
    ("importfail.py", "import math\nmath.sqrt(-1)\n", r"importfail\.py:2: importing the part script raised ValueError"),
])
def test_bad_script_load_errors(tmp_path, name, body, match):
    with pytest.raises(CadfeatError, match=match):
        load_part(write(tmp_path, name, body))


def test_missing_file_and_library_names(tmp_path):
    with pytest.raises(CadfeatError, match=r"part script not found \(library parts: .*thesis_hub"):
        load_part(tmp_path / "nothing.py")
    assert load_part("thesis_hub").path == (PARTS_DIR / "thesis_hub.py").resolve()


def test_part_pickles_by_path():
    import pickle

    part = pickle.loads(pickle.dumps(load_part("thesis_single_hole")))
    assert part.name == "thesis_single_hole" and len(part.holes(radius_mm=2.0)) == 1


@pytest.mark.parametrize("body, match", [
    ("def build(size_mm):\n    raise RuntimeError('kernel said no')\n",
     r"build\(size_mm=12\.0\) raised RuntimeError: kernel said no"),
    ("def build(size_mm):\n    return None\n", r"build\(size_mm=12\.0\) returned None"),
    ("def build(size_mm):\n    return 42\n", r"returned int; it must return a cadquery Workplane"),
    ("def build(size_mm):\n    return cq.Workplane().box(1, 1, 1).faces('>Z')\n", r"returned 0 solids"),
    ("def build(size_mm):\n    return cq.Workplane().box(1, 1, 1).add(cq.Workplane().sphere(5).translate((9, 0, 0)))\n",
     r"returned 2 solids"),
])
def test_bad_build_errors(tmp_path, body, match):
    part = load_part(write(tmp_path, "bad_build.py", GOOD_HEAD + body))
    with pytest.raises(PartBuildError, match=match):
        part.build(size_mm=12.0)


def test_same_stem_different_dirs_do_not_clash(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    body = GOOD_HEAD + "def build(size_mm):\n    return cq.Workplane().box(DIMS, 1)\n"
    pa = load_part(write(tmp_path / "a", "p.py", body.replace("DIMS", "size_mm, 1")))
    pb = load_part(write(tmp_path / "b", "p.py", body.replace("DIMS", "1, size_mm")))
    assert pa.build().BoundingBox().xlen == pytest.approx(10.0)
    assert pb.build().BoundingBox().ylen == pytest.approx(10.0)


# ------------------------------------------------------------------------------- worker-process builds
def test_build_shape_in_worker_equals_in_process():
    part = load_part(PARTS_DIR / "thesis_hub.py")
    params = {"bolt_circle_radius_mm": 11.0, "phase_rad": 0.3}
    remote = build_shape(part, params, timeout_s=60)
    local = part.build(**params)
    assert remote.Volume() == pytest.approx(local.Volume(), rel=1e-12)
    from cadfeat.cad.features import extract_holes
    assert_holes_match(extract_holes(remote), part.expected_holes(**params))


def test_build_shape_timeout_and_errors(tmp_path):
    slow = load_part(write(tmp_path, "slow.py", GOOD_HEAD + "import time\ndef build(size_mm):\n    time.sleep(60)\n"))
    with pytest.raises(PartBuildError, match="exceeded the time limit of 1 s"):
        build_shape(slow, {}, timeout_s=1.0)
    bad = load_part(write(tmp_path, "raises.py", GOOD_HEAD + "def build(size_mm):\n    raise ValueError('nope')\n"))
    with pytest.raises(PartBuildError, match=r"raises\.py: build\(size_mm=10\.0\) raised ValueError: nope"):
        build_shape(bad, None, timeout_s=60)
    with pytest.raises(CadfeatError, match="out of bounds"):
        build_shape(bad, {"size_mm": 99.0})
    dies = load_part(write(tmp_path, "dies.py", GOOD_HEAD + "import os\ndef build(size_mm):\n    os._exit(3)\n"))
    with pytest.raises(PartBuildError, match=r"worker died \(exit code 3\)"):
        build_shape(dies, {}, timeout_s=60)


def test_a_part_carries_its_own_time_limit(tmp_path):
    """``load_part(path, time_limit_s)``: every ``build`` of that part runs in a worker killed after the limit
    (passed explicitly: there is no process-wide limit); None, the default, builds in this process."""
    path = write(tmp_path, "slow.py", GOOD_HEAD + "import time\ndef build(size_mm):\n    time.sleep(60)\n")
    slow = load_part(path, 1.0)
    assert slow.time_limit_s == 1.0 and load_part(path).time_limit_s is None
    with pytest.raises(PartBuildError, match="exceeded the time limit of 1 s"):
        slow.build()
    with pytest.raises(CadfeatError, match="allowed: a number of seconds > 0"):
        load_part(path, 0.0)


# ---------------------------------------------------------------------------------- STEP round trip
@pytest.mark.parametrize("name", ["nema17_mount", "pipe_flange_dn50", "l_bracket"])
def test_step_round_trip_identical_holes(tmp_path, name):
    """export_step → import_step → the same holes (1e-9 mm), kinds and through flags, and the same volume."""
    from cadfeat.cad.export import export_step, shape_volume_mm3, verify_step_roundtrip

    part = load_part(PARTS_DIR / f"{name}.py")
    params = parameter_sets(part)[2]
    solid = part.build(**params)
    path = export_step(solid, tmp_path / f"{name}.step")
    rt = verify_step_roundtrip(path, part.holes(**params), tol_mm=1e-9, prefer_direction=part.view_direction,
                               expected_volume_mm3=shape_volume_mm3(solid))
    assert rt.n_holes == len(part.expected_holes(**params)) and rt.unit == "MM"


# ------------------------------------------------------------------------------------------ the CLI
def test_cli_lists_parts(tmp_path, capsys):
    from cadfeat.cli import main

    assert main(["parts"]) == 0
    out = capsys.readouterr().out
    for path in PART_PATHS:
        assert f"{path.stem}: " in out
    assert "bolt_circle_radius_mm = 9.65 mm in [8.5, 16]" in out and "hole_count = 5 in [3, 8] (integer)" in out
    assert main(["parts", str(PARTS_DIR / "thesis_single_hole.py"), "--holes"]) == 0
    assert "H1: centre (0.000, 0.000, 0.000) mm, axis (0.000, 0.000, 1.000), r 3.700 mm" in capsys.readouterr().out
    write(tmp_path, "broken.py", "def build(:\n")
    assert main(["parts", str(tmp_path)]) == 2
    assert "broken.py:1: syntax error" in capsys.readouterr().err


def test_import_stays_light():
    import subprocess
    import sys

    code = "import sys, cadfeat.cad.parts, cadfeat.cad.design_map; print('cadquery' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


# ------------------------------------------------------------------- STEP re-drill vs parametric rebuild
REDRILL_CASES = {
    "nema17_mount": {"target_face_x_mm": 25.5, "target_face_z_mm": 38.0, "target_base_x_mm": -7.0,
                     "base_hole_x_mm": 27.0},
    "l_bracket": {"base_hole_spacing_mm": 40.0, "base_hole_y_mm": -30.0, "target_upright_z_mm": 30.0},
}


@pytest.mark.parametrize("name", list(REDRILL_CASES))
def test_step_redrill_equals_parametric_rebuild(tmp_path, name):
    """Two independent CAD paths to the same design: re-drilling the STEP export of the default design
    (``step_parts.redrill``) and rebuilding the part script at the new parameters give the same holes
    (1e-9 mm, kinds, depths) and the same volume (1e-9 relative)."""
    from cadfeat.cad.export import export_step
    from cadfeat.cad.step_parts import HoleMove, load_step, redrill

    part = load_part(PARTS_DIR / f"{name}.py")
    new = REDRILL_CASES[name]
    step = load_step(export_step(part.build(), tmp_path / f"{name}.step"), part.view_direction)
    moves = [HoleMove(step.select(list(a["centre"]), tol_mm=1e-9), np.array(b["centre"], float), b["radius_mm"])
             for a, b in zip(part.expected_holes(), part.expected_holes(**new), strict=True)
             if not np.allclose(a["centre"], b["centre"], rtol=0, atol=0)]
    assert len(moves) >= 3
    result = redrill(step.shape, moves)
    reference = part.build(**new)
    assert abs(result.Volume() - reference.Volume()) <= 1e-9 * reference.Volume()
    from cadfeat.cad.features import extract_holes

    redrilled = extract_holes(result, prefer_direction=part.view_direction)
    assert_holes_match(redrilled, part.expected_holes(**new))
    depth = {tuple(np.round(h.centre, 6)): (h.depth_mm, h.through) for h in part.holes(**new)}
    for h in redrilled:
        d, through = depth[tuple(np.round(h.centre, 6))]
        assert abs(h.depth_mm - d) <= 1e-9 and h.through == through


def test_redrill_refuses_a_hole_on_a_curved_face(tmp_path):
    """The brake hub's radial hole enters a cylindrical face: re-drilling says so instead of guessing."""
    from cadfeat.cad.export import export_step
    from cadfeat.cad.step_parts import HoleMove, load_step, redrill

    part = load_part(PARTS_DIR / "brake_disc_hub.py")
    step = load_step(export_step(part.build(), tmp_path / "hub.step"), part.view_direction)
    hole = step.select([35.0, 0.0, 18.0], tol_mm=1e-9)
    with pytest.raises(CadfeatError, match=r"\(35, 0, 18\).*not perpendicular to its axis"):
        redrill(step.shape, [HoleMove(hole, np.array([35.0, 0.0, 20.0]), hole.radius_mm)])
