"""Benchmark: re-drilling a STEP part and writing verified outputs.

Times, on the fixture plate of tests/data (5 holes: plain, counterbore, countersink, blind), the steps a
study runs for a STEP part after optimisation: ``redrill`` of 4 holes, ``export_step`` +
``verify_step_roundtrip``, ``export_stl`` + ``check_stl``. Baseline, measured in the same run: building
the same re-designed plate directly from its CadQuery script (what a parametric part costs instead).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from benchutil import load as _load
from benchutil import median_ms as _median_ms
from benchutil import save_section


def main(quick: bool = False) -> str:
    import numpy as np

    from cadfeat.cad.export import check_stl, export_step, export_stl, shape_volume_mm3, verify_step_roundtrip
    from cadfeat.cad.features import extract_holes
    from cadfeat.cad.step_parts import HoleMove, load_step, redrill

    machine = _load("run_all", HERE / "run_all.py").machine_description()
    fx = _load("make_fixtures", ROOT / "tests" / "data" / "make_fixtures.py")
    moved = {"A": ((-30.0, -20.0), 10.0), "CBORE": ((15.0, -15.0), 9.0), "CSINK": ((25.0, 15.0), 12.0),
             "BLIND": ((0.0, 5.0), 4.0)}
    old = {"A": fx.PLAIN["A"][0], "CBORE": fx.CBORE[0], "CSINK": fx.CSINK[0], "BLIND": fx.BLIND[0]}
    thickness = fx.PLATE[2]
    repeats = 3 if quick else 15

    part = load_step(ROOT / "tests" / "data" / fx.STEP_NAME)
    moves = [HoleMove(part.select((*old[n], thickness)), np.array([*xy, thickness]), dia / 2)
             for n, (xy, dia) in moved.items()]
    result = redrill(part.shape, moves)
    holes = extract_holes(result)
    volume = shape_volume_mm3(result)
    with tempfile.TemporaryDirectory() as tmp:
        step, stl = Path(tmp) / "r.step", Path(tmp) / "r.stl"
        rows = [
            ("baseline: CadQuery build of the re-designed plate", _median_ms(lambda: fx.build_plate(moved=moved),
                                                                              repeats)),
            ("load_step (import + hole extraction)", _median_ms(lambda: load_step(part.path), repeats)),
            ("redrill 4 holes (fill, unify, cut, checks)", _median_ms(lambda: redrill(part.shape, moves), repeats)),
            ("export_step", _median_ms(lambda: export_step(result, step), repeats)),
            ("verify_step_roundtrip", _median_ms(lambda: verify_step_roundtrip(step, holes, expected_volume_mm3=volume),
                                                 repeats)),
            ("export_stl (0.01 mm)", _median_ms(lambda: export_stl(result, stl, 0.01), repeats)),
            ("check_stl", _median_ms(lambda: check_stl(stl, result, 0.01), repeats)),
        ]
        rt = verify_step_roundtrip(step, holes, expected_volume_mm3=volume)
    base = rows[0][1]
    lines = [
        "## Re-drilling a STEP part and verified export (bench_redrill)",
        "",
        f"Machine: {machine}. Median of {repeats} runs; fixture plate (tests/data/plate_holes.step), 4 of its",
        "5 holes moved and resized. Ratio: time / baseline (building the same plate from its CadQuery script).",
        "",
        "| step | time (ms) | ratio to baseline |",
        "|---|---:|---:|",
    ]
    lines += [f"| {name} | {ms:.1f} | {ms / base:.2f} |" for name, ms in rows]
    lines += [
        "",
        f"STEP round trip of the re-drilled plate: {rt.n_holes} holes, max centre error "
        f"{rt.max_centre_error_mm:.1e} mm, max radius error {rt.max_radius_error_mm:.1e} mm, volume relative "
        f"error {rt.volume_rel_error:.1e}.",
    ]
    return save_section("bench_redrill", "\n".join(lines))


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
