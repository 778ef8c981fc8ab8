"""Issue 32 item 4: a corpus of CadQuery scripts written by others, in their styles (tests/data/cqgi/SOURCES.md says
where each comes from, its licence and what was changed).

For every script of the corpus: ``cadfeat parts SCRIPT --params`` lists every top-level constant with its value,
``cadfeat validate`` passes on its study, ``score_design`` at the study's start succeeds, a short study succeeds,
and the holes the study keeps fixed come back where the script put them.

References, none of them cadfeat code: the constants are read from the script's text by regular expressions
(``_text_constants``); the holes the script's geometry defines are the cylinders and cones of CadQuery's own CQGI
build of the script (``cqgi_helpers.cqgi_solid``) and of the exported STEP, read through OCP (``_surfaces``).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import tomllib
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from cqgi_helpers import cqgi_solid

DATA = Path(__file__).parents[1] / "data" / "cqgi"

#: The scripts written out here: script -> (its study, the number of holes the study keeps fixed by the script's
#: drawing (holes no varied constant moves or resizes), the kinds of its holes by the drawing). Every script in
#: tests/data/cqgi is tested (a script added there with a ``*_study.toml`` naming it is picked up); these add the
#: hand-written expectations.
KNOWN = {
    "Ex002_Block_With_Bored_Center_Hole.py": ("ex002", 0, {"plain": 1}),
    "Ex003_Pillow_Block_With_Counterbored_Holes.py": ("ex003", 0, {"counterbore": 4, "plain": 1}),
    "Ex007_Using_Point_Lists.py": ("ex007", 0, {"plain": 4}),
    "Ex019_Counter_Sunk_Holes.py": ("ex019", 0, {"countersink": 4}),
    "doc_bearing_pillow_block.py": ("pillow", 1, {"counterbore": 4, "plain": 1}),   # fixed: the bearing bore
    # the lid's screw holes: the bottom's posts left a Ø10 x 1 recess round each (seen first from the flipped
    # lid's top), the counterbore at the far end
    "doc_parametric_enclosure.py": ("enclosure", 0, {"counterbore": 4}),
    "vesa_plate.py": ("vesa", 0, {"plain": 5}),
    "offset_bracket.py": ("offset", 0, {"plain": 3}),
    "dowel_plate.py": ("dowel", 2, {"plain": 3}),                                    # the two dowel holes
    "manifold_block.py": ("manifold", 4, {"plain": 4, "counterbore": 2}),            # side ports, mounting holes
    "warehouse_flange.py": ("flange", 2, {"plain": 8}),                              # bore, radial set screw
    "algebra_bracket.py": ("bracket", 2, {"plain": 3, "counterbore": 2}),           # the counterbored base holes
}


def _studies() -> dict[str, Path]:
    """script name -> the study file in tests/data/cqgi whose ``[study] part`` it is."""
    out = {}
    for path in sorted(DATA.glob("*_study.toml")):
        out.setdefault(tomllib.loads(path.read_text())["study"]["part"], path)
    return out


SCRIPTS = sorted(p.name for p in DATA.glob("*.py"))
STUDIES = _studies()
STUDIED = [s for s in SCRIPTS if s in STUDIES]

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_LITERAL = rf"{_NUMBER}|True|False|\"[^\"\n]*\"|'[^'\n]*'"


def _value(text: str) -> Any:
    if text in ("True", "False"):
        return text == "True"
    if text[0] in "\"'":
        return text[1:-1]
    return float(text) if re.search(r"[.eE]", text) else int(text)


def _literal(text: str) -> tuple[bool, Any]:
    """(True, value) for a literal (a number, bool, string, or a tuple of them, parenthesised or not)."""
    text = text.strip()
    if re.fullmatch(_LITERAL, text):
        return True, _value(text)
    inner = text[1:-1] if text.startswith("(") and text.endswith(")") else text
    items = [v.strip() for v in inner.split(",")]
    if "," in inner and all(re.fullmatch(_LITERAL, v) for v in items if v) and items[0]:
        return True, tuple(_value(v) for v in items if v)
    return False, None


def _without_comment(line: str) -> str:
    """``line`` without its ``# comment`` (a ``#`` inside a string literal is no comment)."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch == "#":
            return line[:i].rstrip()
    return line.rstrip()


def _text_constants(path: Path) -> list[tuple[str, str | None, Any]]:
    """(name, type, value) of each top-level constant as the script's text sets it, read line by line with regular
    expressions, independently of cadfeat's syntax-tree reader: statements at column 0 ``name = literal``,
    ``name: type = literal``, ``name = (\\n literal  # comment\\n)``, ``a, b = 1.0, 2.0`` / ``(a, b) = (...)``
    (each name whose value is a literal), a literal being a number, bool, string or a tuple of them (type None,
    value a list). A name assigned a literal again keeps its last value at its first place; one assigned anything
    else (or augmented, ``+=``, or chained, ``a = b = 1``) is no constant."""
    text = re.sub(rf"=[ \t]*\([ \t]*\n[ \t]*({_LITERAL})[ \t]*(?:#[^\n]*)?\n[ \t]*\)", r"= \1", path.read_text())
    found: dict[str, Any] = {}
    for line in text.splitlines():
        code = _without_comment(line)
        if m := re.match(r"^([A-Za-z_]\w*)\s*(?:[-+*/%@&|^]|//|\*\*|<<|>>)=", code):   # augmented
            found.pop(m.group(1), None)
        elif m := re.match(r"^([A-Za-z_]\w*)\s*=\s*([A-Za-z_]\w*)\s*=[^=]", code):      # chained
            found.pop(m.group(1), None)
            found.pop(m.group(2), None)
        elif m := re.match(r"^\(?\s*([A-Za-z_]\w*(?:\s*,\s*[A-Za-z_]\w*)+)\s*,?\s*\)?\s*=(?!=)\s*(.*)$", code):
            names = [n.strip() for n in m.group(1).split(",")]
            rhs = m.group(2).strip()
            values = [v.strip() for v in (rhs[1:-1] if rhs.startswith("(") and rhs.endswith(")") else rhs).split(",")]
            for name, value in zip(names, values if len(values) == len(names) else [""] * len(names), strict=True):
                ok, v = _literal(value)
                if ok:
                    found[name] = v
                else:
                    found.pop(name, None)
        elif m := re.match(r"^([A-Za-z_]\w*)\s*(?::\s*[\w.\[\], ]+)?\s*=(?!=)\s*(.*)$", code):
            ok, v = _literal(m.group(2))
            if ok:
                found[m.group(1)] = v
            else:
                found.pop(m.group(1), None)
    out: list[tuple[str, str | None, Any]] = []
    for name, value in found.items():
        kind = "boolean" if isinstance(value, bool) else "string" if isinstance(value, str) else \
            None if isinstance(value, tuple) else "number"
        out.append((name, kind, list(value) if isinstance(value, tuple) else value))
    return out


def test_the_corpus():
    """At least 12 scripts, each with a study; the scripts written out here in SOURCES.md, each with its study."""
    assert len(SCRIPTS) >= 12 and STUDIED == SCRIPTS
    sources = (DATA / "SOURCES.md").read_text()
    for script, (study, _, _) in KNOWN.items():
        assert f"`{script}`" in sources and f"`{study}_study.toml`" in sources, script
        assert STUDIES[script] == DATA / f"{study}_study.toml"


@pytest.mark.parametrize("script", SCRIPTS)
def test_params_lists_every_constant(script, capsys):
    from cadfeat.cli import main

    path = DATA / script
    assert main(["parts", str(path), "--params"]) == 0
    listed = json.loads(capsys.readouterr().out)
    expected = _text_constants(path)
    assert [(d["name"], d.get("type"), d["initial"]) for d in listed] == expected
    assert [type(d["initial"]) for d in listed] == [type(v) for _, _, v in expected]  # 3 stays an int, 3.0 a float
    assert any(k == "number" for _, k, _ in expected)


TRICKY = """import cadquery as cq
from math import pi

SIZE = (40.0, 30.0)          # a tuple: listed, no design parameter
width, depth = 40.0, pi      # depth is computed: no constant
(rows, cols) = (2, 3)
thickness = (
    6.0  # a parenthesised literal on its own line
)
hole = 5.0
hole = 6.0                   # assigned again: its last value
scale = 1.0
scale *= 2                   # augmented: no constant
a = b = 3.0                  # chained: neither
label = "plate # 1"          # a '#' in a string
flag: bool = True
count: int = +4
tiny = .5e-1
result = cq.Workplane("XY").box(width, SIZE[1], thickness).faces(">Z").workplane().hole(hole)
show_object(result)
"""


def test_params_of_tricky_constants(tmp_path, capsys):
    """``--params`` on constants written every way a script writes them, against a hand-written list and against
    the text reader the corpus tests use."""
    from cadfeat.cli import main

    path = tmp_path / "tricky.py"
    path.write_text(TRICKY)
    expected = [("SIZE", None, [40.0, 30.0]), ("width", "number", 40.0), ("rows", "number", 2),
                ("cols", "number", 3), ("thickness", "number", 6.0), ("hole", "number", 6.0),
                ("label", "string", "plate # 1"), ("flag", "boolean", True), ("count", "number", 4),
                ("tiny", "number", 0.05)]
    assert _text_constants(path) == expected
    assert main(["parts", str(path), "--params"]) == 0
    assert [(d["name"], d.get("type"), d["initial"]) for d in json.loads(capsys.readouterr().out)] == expected


def _study_file(study: Path, folder: Path, **optimizer: int) -> Path:
    """The corpus study with its part's absolute path and the optimiser's ``starts`` / ``maxiter`` set."""
    text = re.sub(r"""^(part\s*=\s*)["']([^"'/][^"']*)["']""", lambda m: f'{m.group(1)}"{DATA / m.group(2)}"',
                  study.read_text(), count=1, flags=re.M)
    if not re.search(r"^\[optimizer\]$", text, flags=re.M):
        text += "\n[optimizer]\n"
    for key, value in optimizer.items():
        text, n = re.subn(rf"^{key} = \d+$", f"{key} = {value}", text, flags=re.M)
        if not n:
            text, n = re.subn(r"^\[optimizer\]$", f"[optimizer]\n{key} = {value}", text, flags=re.M)
        assert n == 1, key
    path = folder / study.name
    path.write_text(text)
    return path


def _surfaces(solid: Any) -> list[tuple[str, Any]]:
    """(kind, OCP surface) of each face of ``solid``: 'cylinder' / 'cone' (gp_Cylinder / gp_Cone), or 'other'
    (the face's Geom surface)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cone, GeomAbs_Cylinder

    out = []
    for face in solid.Faces():
        s = BRepAdaptor_Surface(face.wrapped)
        kind = s.GetType()
        if kind == GeomAbs_Cylinder:
            out.append(("cylinder", s.Cylinder()))
        elif kind == GeomAbs_Cone:
            out.append(("cone", s.Cone()))
        else:
            out.append(("other", BRep_Tool.Surface_s(face.wrapped)))
    return out


def _axis_line(surface: Any) -> tuple[np.ndarray, np.ndarray]:
    ax = surface.Axis()
    p, d = ax.Location(), ax.Direction()
    return np.array([p.X(), p.Y(), p.Z()]), np.array([d.X(), d.Y(), d.Z()])


def _on_line(centre: np.ndarray, axis: np.ndarray, surface: Any, tol: float = 1e-6) -> bool:
    p, d = _axis_line(surface)
    return abs(abs(float(np.dot(d, axis))) - 1.0) < 1e-9 and float(np.linalg.norm(np.cross(centre - p, d))) < tol


def _on_a_face(centre: np.ndarray, surfaces: list[tuple[str, Any]]) -> bool:
    """The centre lies on the (untrimmed) surface of a face of the solid: the host face the hole opens in."""
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.gp import gp_Pnt

    point = gp_Pnt(*map(float, centre))
    for kind, s in surfaces:
        if kind == "other":
            proj = GeomAPI_ProjectPointOnSurf(point, s)
            if proj.NbPoints() and proj.LowerDistance() < 1e-6:
                return True
        elif kind == "cylinder":  # a hole opening in a curved face (the flange's set screw, into the hub)
            p, d = _axis_line(s)
            if abs(float(np.linalg.norm(np.cross(centre - p, d))) - s.Radius()) < 1e-6:
                return True
    return False


def _is_the_scripts_hole(hole: dict, surfaces: list[tuple[str, Any]]) -> bool:
    """``hole`` (results.json) is a hole of the solid with ``surfaces``: a concentric cylinder of its radius (a
    countersink's or chamfered rim's entrance radius is its cone's: then a concentric cone and a narrower
    concentric cylinder), and its centre on a face of the solid."""
    c, a, r = np.asarray(hole["centre_mm"]), np.asarray(hole["axis"]), float(hole["radius_mm"])
    cylinders = [s for k, s in surfaces if k == "cylinder" and _on_line(c, a, s)]
    if hole["kind"].startswith("countersink") or "chamfered" in hole["kind"]:
        coaxial = any(_on_line(c, a, s) for k, s in surfaces if k == "cone")
        found = coaxial and any(s.Radius() < r - 1e-9 for s in cylinders)
    else:
        found = any(abs(s.Radius() - r) < 1e-6 for s in cylinders)
    return found and _on_a_face(c, surfaces)


@pytest.mark.parametrize("script", STUDIED)
def test_validate_score_and_a_short_study(script, tmp_path, monkeypatch, capsys):
    """``cadfeat validate``; ``score_design`` at the start (every kept requirement holds, the holes are the
    script's); a one-iteration study whose optimised STEP has the holes of CQGI's own build at the reported
    optimum, the fixed holes where the script's default build has them, and a source script never changed."""
    import cadquery as cq

    from cadfeat.cad.features import extract_holes
    from cadfeat.cli import main
    from cadfeat.study import run as study_mod
    from cadfeat.study.designs import score_design

    part_path = DATA / script
    before_text = part_path.read_bytes()
    config = _study_file(STUDIES[script], tmp_path, starts=1, maxiter=1)
    assert main(["validate", str(config)]) == 0
    assert ": ok — study" in capsys.readouterr().out

    original = cqgi_solid(part_path, {})
    surfaces0 = _surfaces(original)
    start = score_design(config)
    assert start["requirements_hold"], [c for c in start["requirements"] if not c["ok"]]
    assert start["combined"] is not None and math.isfinite(start["combined"])
    assert all(_is_the_scripts_hole(h, surfaces0) for h in start["holes"])
    assert len(start["holes"]) == len(extract_holes(original))
    if script in KNOWN:
        assert Counter(h["kind"] for h in start["holes"]) == KNOWN[script][2]

    monkeypatch.setattr(study_mod, "_report", lambda *a, **k: None)  # the report is tested elsewhere
    with contextlib.redirect_stdout(io.StringIO()):
        study_mod.run_study(config, tmp_path / "out", quiet=True, progress=False)
    results = json.loads((tmp_path / "out" / "results.json").read_text())
    params = {v["name"]: v["after"] for v in results["variables"]}
    assert params and all(v["lower"] - 1e-9 <= v["after"] <= v["upper"] + 1e-9 for v in results["variables"])
    exported = cq.importers.importStep(str(tmp_path / "out" / "optimised.step")).val()
    got = sorted((tuple(np.round(h.centre, 4)), round(h.radius_mm, 4)) for h in extract_holes(exported))
    want = sorted((tuple(np.round(h.centre, 4)), round(h.radius_mm, 4))
                  for h in extract_holes(cqgi_solid(part_path, params)))
    assert got == want

    before = {h["name"]: h for h in results["holes"]["before"]}
    fixed = [h for h in results["holes"]["after"] if h["fixed"]]
    if script in KNOWN:
        assert len(fixed) == KNOWN[script][1]
    assert all(c["ok"] for c in results["constraints"] if c["name"] == "fixed")
    surfaces1 = _surfaces(exported)
    for h in fixed:
        h0 = before[h["name"]]
        np.testing.assert_allclose(h["centre_mm"], h0["centre_mm"], atol=1e-6)
        assert h["radius_mm"] == pytest.approx(h0["radius_mm"], abs=1e-9)
        assert _is_the_scripts_hole(h0, surfaces0), h0  # where the script's own build has it
        assert _is_the_scripts_hole(h, surfaces1), h    # and there again in the optimised STEP
    defaults = {name: value for name, _, value in _text_constants(part_path)}
    for v in results["variables"]:  # no varied constant moves a fixed hole: each one varied alone, built by CQGI
        x, mid = float(defaults[v["name"]]), 0.5 * (v["lower"] + v["upper"])
        x = x + 0.5 * (mid - x) if abs(mid - x) > 1e-9 else x + 0.25 * (v["upper"] - x)
        varied = _surfaces(cqgi_solid(part_path, {v["name"]: round(x) if isinstance(defaults[v["name"]], int)
                                                  else x}))
        assert all(_is_the_scripts_hole(before[h["name"]], varied) for h in fixed), v["name"]
    assert part_path.read_bytes() == before_text
