"""Compare cadfeat's holes of a real third-party STEP part with its recorded truth (``shared/real_step``).

The corpus lives beside the repository (``<repo>/../shared/real_step``: 15 STEP files, ``truth.json`` with
their true holes found with OCP only, ``SOURCES.md`` with origin and licence); it is never copied into the
repository. ``CADFEAT_REAL_STEP`` overrides the folder.

Truth conventions (``truth.json`` "about"): centre = centre of the entrance rim on its host face, axis out of
the material there, ``diameters`` from the entrance inwards, ``kind`` without rim chamfers/fillets, ``depth`` =
axial length of the wall, ``entrance_either_end`` = either end of a plain through hole is a right entrance.
Used by ``tests/cad/test_real_step_parts.py`` and by ``python tests/real_step_truth.py`` (the score table).
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
AXIS_TOL_RAD = 2e-3
"""Largest angle between an extracted axis and the true one (the truth is rounded to 1e-6)."""


def real_step_dir() -> Path | None:
    """``$CADFEAT_REAL_STEP``, else the first ``shared/real_step`` beside the repository or an ancestor of it
    (a git worktree sits one level deeper than a clone); None if there is none."""
    if env := os.environ.get("CADFEAT_REAL_STEP"):
        return Path(env)
    for parent in REPO.parents:
        if (parent / "shared" / "real_step" / "truth.json").is_file():
            return parent / "shared" / "real_step"
    return None


@cache
def truth() -> dict[str, Any]:
    """``truth.json``'s parts: file name -> part record."""
    folder = real_step_dir()
    assert folder is not None, "no shared/real_step beside the repository"
    return json.loads((folder / "truth.json").read_text())["parts"]


def length_tol(size_mm: float) -> float:
    """Tolerance of a length of ``size_mm`` (mm): 0.02 mm plus 0.5 % (truth rounded to 1e-3, real exports'
    B-rep tolerances up to 1e-2)."""
    return 0.02 + 0.005 * abs(size_mm)


# ------------------------------------------------------------------------------------------------ truth
@dataclass(frozen=True)
class Entrance:
    """One acceptable reading of a true hole: entrance centre, axis out of the material, kinds, depth."""

    centre: np.ndarray
    axis: np.ndarray
    kinds: tuple[str, ...]
    depth: float
    entrance_dia: float


def _shifted(centre: np.ndarray, text: str) -> np.ndarray | None:
    """The centre with a coordinate set as ``text`` says ("entrance z=0", "z=15 (ledge side ...)")."""
    m = re.search(r"\b([xyz])=(-?[0-9.]+)", text)
    if not m:
        return None
    c = centre.copy()
    c["xyz".index(m.group(1))] = float(m.group(2))
    return c


def entrances(t: dict[str, Any]) -> list[Entrance]:
    """Every acceptable entrance of true hole ``t``: its own, the other end of a plain through hole, and the
    recorded alternatives (``entrance_alternatives``, ``kind_also_accepted``) with the depth they imply."""
    c, a = np.array(t["centre"], float), np.array(t["axis"], float)
    out = [Entrance(c, a, (t["kind"],), float(t["depth"]), float(t["diameters"][0]))]
    if t.get("entrance_either_end"):
        out.append(Entrance(np.array(t["other_end_centre"], float), -a, (t["kind"],), float(t["depth"]),
                            float(t["diameters"][-1])))
    for text in t.get("entrance_alternatives", []):
        if (alt := _shifted(c, text)) is not None:
            out.append(Entrance(alt, a, (t["kind"],), float(t["depth"]) - abs(float((c - alt) @ a)),
                                float(t["diameters"][0])))
    for text in t.get("kind_also_accepted", []):
        kind = text.split()[0]
        if (alt := _shifted(c, text)) is not None:  # the far end: the axis turns round
            far = -a if float((alt - c) @ a) < 0 else a
            dia = float(re.search(r"Ø([0-9.]+)", text).group(1)) if "Ø" in text else float(t["diameters"][-1])
            out.append(Entrance(alt, far, (kind,), float(t["depth"]), dia))
        else:  # at the same end: its own entrance diameter where the text gives one ("countersink (Ø3.8, ...")
            dia = float(re.search(r"Ø([0-9.]+)", text).group(1)) if "Ø" in text else float(t["diameters"][0])
            out.append(Entrance(c, a, (kind,), float(t["depth"]), dia))
    return out


# ------------------------------------------------------------------------------------------- comparing
def on_line(hole: Any, t: dict[str, Any]) -> bool:
    """The extracted hole lies on the true hole's axis line (either direction)."""
    a = np.array(t["axis"], float)
    h_axis = np.asarray(hole.axis, float)
    if np.linalg.norm(np.cross(h_axis, a)) > AXIS_TOL_RAD:
        return False
    off = np.asarray(hole.centre, float) - np.array(t["centre"], float)
    return float(np.linalg.norm(np.cross(off, a))) <= length_tol(t["bore_diameter"])


def along(hole: Any, t: dict[str, Any]) -> float:
    """Distance (mm) of the extracted centre from the nearest true end of the hole along its axis line."""
    c = np.asarray(hole.centre, float)
    ends = [np.array(t["centre"], float)] + [np.array(t[k], float) for k in ("other_end_centre", "bottom_centre")
                                             if k in t]
    return min(float(np.linalg.norm(c - e)) for e in ends)


def match(true_holes: list[dict[str, Any]], holes: list[Any]) -> list[Any | None]:
    """For each true hole, the extracted hole on its axis line whose centre is nearest one of its ends (each
    extracted hole used once, coaxial holes in separate walls kept apart); None where there is none."""
    pairs = sorted((along(h, t), i, j) for i, t in enumerate(true_holes) for j, h in enumerate(holes) if on_line(h, t))
    out: list[Any | None] = [None] * len(true_holes)
    used: set[int] = set()
    for dist, i, j in pairs:
        if out[i] is None and j not in used and dist <= 0.5 * float(true_holes[i]["depth"]) + 0.1:
            out[i], _ = holes[j], used.add(j)
    return out


def hole_errors(hole: Any, t: dict[str, Any]) -> list[str]:
    """What is wrong with extracted ``hole`` against true hole ``t`` (empty if right): entrance (centre and axis
    of an acceptable entrance), kind, through, depth, bore and entrance diameters."""
    best: list[str] | None = None
    for e in entrances(t):
        errs = []
        if float(np.linalg.norm(np.asarray(hole.centre) - e.centre)) > length_tol(e.depth):
            errs.append(f"entrance {np.round(hole.centre, 3).tolist()} (true {np.round(e.centre, 3).tolist()})")
        if float(np.linalg.norm(np.asarray(hole.axis) - e.axis)) > AXIS_TOL_RAD:
            errs.append(f"axis {np.round(hole.axis, 3).tolist()} (true {np.round(e.axis, 3).tolist()})")
        if hole.base_kind not in e.kinds:
            errs.append(f"kind {hole.kind!r} (true {'/'.join(e.kinds)})")
        if hole.through != bool(t["through"]):
            errs.append(f"through={hole.through} (true {t['through']})")
        if abs(hole.depth_mm - e.depth) > length_tol(e.depth):
            errs.append(f"depth {hole.depth_mm:.4g} (true {e.depth:.4g})")
        if abs(2 * hole.bore_radius_mm - t["bore_diameter"]) > length_tol(t["bore_diameter"]):
            errs.append(f"bore Ø{2 * hole.bore_radius_mm:.4g} (true Ø{t['bore_diameter']:.4g})")
        if hole.rim == "sharp" and abs(2 * hole.radius_mm - e.entrance_dia) > length_tol(e.entrance_dia):
            errs.append(f"entrance Ø{2 * hole.radius_mm:.4g} (true Ø{e.entrance_dia:.4g})")
        if best is None or len(errs) < len(best):
            best = errs
    return best or []


def part_report(part: Any) -> dict[str, list[str]]:
    """True hole id -> errors for one loaded part (``"extra"`` lists extracted holes that are no true hole)."""
    rec = truth()[part.path.name]
    found = match(rec["holes"], list(part.holes))
    out = {t["id"]: (["not found"] if h is None else hole_errors(h, t)) for t, h in zip(rec["holes"], found,
                                                                                          strict=True)}
    matched = {id(h) for h in found if h is not None}
    extra = [f"{h.name} {h.kind} Ø{2 * h.radius_mm:.4g} at {np.round(h.centre, 3).tolist()}" for h in part.holes
             if id(h) not in matched]
    if extra:
        out["extra"] = extra
    return out


# ------------------------------------------------------------------------------------------ re-drilling
def move_direction(part: Any, hole: Any) -> np.ndarray:
    """A unit direction in the hole's host face to move it by: of ±u, ±v of the host outline the one that
    leaves the most room to the face's boundaries, cut-outs and other holes (deterministic); a direction
    perpendicular to the axis on a non-planar host."""
    outline = hole.outline
    if outline is None:
        a = np.asarray(hole.axis, float)
        helper = np.eye(3)[int(np.argmin(np.abs(a)))]
        d = np.cross(a, helper)
        return d / np.linalg.norm(d)
    polys = [outline.outer, *outline.keepouts]
    others = [(outline.to_face(o.centre), o.radius_mm) for o in part.holes
              if o is not hole and o.host_face == hole.host_face]
    start = outline.to_face(hole.centre)

    def room(d2: np.ndarray) -> float:
        p = start + 0.5 * d2
        gaps = [_poly_distance(p, poly) for poly in polys]
        gaps += [float(np.linalg.norm(p - c)) - r for c, r in others]
        return min(gaps) - hole.radius_mm

    dirs = [np.array(d, float) for d in ((1, 0), (-1, 0), (0, 1), (0, -1))]
    best = max(dirs, key=room)
    return best[0] * np.asarray(outline.u, float) + best[1] * np.asarray(outline.v, float)


def _poly_distance(p: np.ndarray, poly: np.ndarray) -> float:
    a, b = poly, np.roll(poly, -1, axis=0)
    ab = b - a
    s = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-30), 0, 1)
    return float(np.min(np.linalg.norm(a + s[:, None] * ab - p, axis=1)))


def same_hole(a: Any, b: Any, tol: float = 1e-3) -> list[str]:
    """Differences between two extracted holes (centre, axis, radii, depth, kind, through); tol in mm."""
    errs = []
    if np.linalg.norm(np.asarray(a.centre) - np.asarray(b.centre)) > tol:
        errs.append(f"centre {np.round(a.centre, 4).tolist()} != {np.round(b.centre, 4).tolist()}")
    if np.linalg.norm(np.asarray(a.axis) - np.asarray(b.axis)) > 1e-6 + AXIS_TOL_RAD * 0.01:
        errs.append(f"axis {np.round(a.axis, 5).tolist()} != {np.round(b.axis, 5).tolist()}")
    for name in ("radius_mm", "bore_radius_mm", "depth_mm"):
        if abs(getattr(a, name) - getattr(b, name)) > tol:
            errs.append(f"{name} {getattr(a, name):.5g} != {getattr(b, name):.5g}")
    if a.kind != b.kind or a.through != b.through:
        errs.append(f"{a.kind}/{'through' if a.through else 'blind'} != {b.kind}/{'through' if b.through else 'blind'}")
    return errs


def redrill_errors(part: Any, hole: Any, offset: np.ndarray) -> list[str]:
    """Re-drill ``hole`` of ``part`` moved by ``offset`` (mm, in its host face), re-extract, and list what
    differs from the expected holes: the moved hole at its new centre with everything else of it unchanged,
    every other hole exactly as before."""
    import dataclasses

    from cadfeat.cad.features import extract_holes
    from cadfeat.cad.step_parts import HoleMove, redrill
    from cadfeat.errors import CadfeatError

    centre = np.asarray(hole.centre, float) + offset
    try:
        shape = redrill(part.shape, [HoleMove(hole, centre, hole.radius_mm)], part.tolerance, part.path,
                        verify=False)  # the re-extraction below checks more than redrill's own verification
    except CadfeatError as exc:
        return [f"refused: {exc}"]
    found = extract_holes(shape, tol=part.tolerance)
    expected = [dataclasses.replace(h, centre=centre) if h is hole else h for h in part.holes]
    errs = []
    if len(found) != len(expected):
        errs.append(f"{len(found)} holes after re-drilling, {len(expected)} before")
    tol = max(1e-3, 10 * part.tolerance.linear_mm)
    for e in expected:
        near = [f for f in found if np.linalg.norm(np.asarray(f.centre) - e.centre) <= tol
                and np.linalg.norm(np.asarray(f.axis) - e.axis) < 1e-3]
        if not near:
            errs.append(f"{e.name}: not found at {np.round(e.centre, 4).tolist()}")
        elif diffs := same_hole(near[0], e, tol):
            errs.append(f"{e.name}: {'; '.join(diffs)}")
    return errs


def redrill_subset(part: Any, most: int = 12) -> list[Any]:
    """The holes to re-drill in the tests: all of them on a part with at most ``most`` holes, else every
    hole of a class (kind, entrance radius, through, host face) not yet seen plus every k-th hole up to
    ``most`` (deterministic: by name order)."""
    holes = list(part.holes)
    if len(holes) <= most:
        return holes
    seen, out = set(), []
    for h in holes:
        key = (h.kind, round(h.radius_mm, 3), h.through, h.host_face)
        if key not in seen:
            seen.add(key)
            out.append(h)
    step = max(1, len(holes) // max(1, most - len(out)))
    out += [h for h in holes[::step] if h not in out][: max(0, most - len(out))]
    return sorted(out, key=lambda h: int(h.name[1:]))


def main() -> None:
    """Print the score: holes right / total, re-drills (in place and moved 0.5 mm) right / total."""
    import sys
    import time

    from cadfeat.cad.step_parts import load_step

    only = sys.argv[1:]
    folder = real_step_dir()
    holes_ok = holes_n = rd_ok = rd_n = 0
    for name, rec in truth().items():
        if only and not any(o in name for o in only):
            continue
        t0 = time.time()
        part = load_step(folder / name)
        rep = part_report(part)
        bad = {k: v for k, v in rep.items() if v}
        holes_n += len(rec["holes"])
        holes_ok += sum(1 for t in rec["holes"] if not rep[t["id"]])
        print(f"{name}: {len(part.holes)} holes found, {len(rec['holes'])} true ({time.time() - t0:.1f}s)")
        for k, v in bad.items():
            print(f"   {k}: {'; '.join(v)}")
        for h in redrill_subset(part):
            for label, off in (("in place", np.zeros(3)), ("moved 0.5", 0.5 * move_direction(part, h))):
                rd_n += 1
                errs = redrill_errors(part, h, off)
                rd_ok += not errs
                if errs:
                    print(f"   redrill {h.name} {label}: {'; '.join(errs)[:400]}")
        print(f"   ({time.time() - t0:.1f}s)", flush=True)
    print(f"holes right: {holes_ok} / {holes_n}; re-drills right: {rd_ok} / {rd_n}")


if __name__ == "__main__":
    main()
