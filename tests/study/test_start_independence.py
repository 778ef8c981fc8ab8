"""The optimum does not depend on the starting design (issue 16 item 2), on every study with a design variable.

Script studies: the part script is copied with other defaults for the design variables (the part's current
dimensions, which the optimiser starts from) — two other feasible values per study — and the study's own
set-up and optimise phase (``setup_study`` + ``optimise``, or the CAD trust-region loop ``solve_with_cad`` for a
nonlinear design map; no export, verification or report) must give the same optimum, to 1e-3 of each
variable's range, and the same combined objective (on a plateau of the objective: the same objectives in their
physical units to 0.3 %, ``PLATEAU_TOL``). STEP studies have no defaults: the start is the file's
holes, which ARE the geometry; their start is changed by giving the design space other feasible initial
offsets/diameters (what the optimiser starts from), the model staying anchored on the file.
"""

from __future__ import annotations

import copy
import dataclasses
import tomllib
from pathlib import Path

import numpy as np
import pytest

from cadfeat.design.optimize import optimise, solve_with_cad
from cadfeat.design.problem import Problem
from cadfeat.study.schema import load_study
from cadfeat.study.setup import setup_study

STUDIES = Path(__file__).parents[2] / "studies"
ALL = sorted(p.stem for p in STUDIES.glob("*.toml"))
#: Where the two other starts lie: this fraction of the way from the part's defaults towards the point at the
#: given fraction of each variable's range (feasible and buildable on every library part).
TOWARDS, FRACTIONS = 0.5, (0.15, 0.85)
X_TOL = 1e-3  # of each variable's range
COMBINED_TOL = 1e-6
#: The flagship's g_POSE has a plateau along the base target's x (the detection model's association term: which
#: far-face hole projects near it in a few frames): from two starts the optimum lands at x = 15 mm and −11.4 mm
#: with predicted errors 0.13 % apart (0.05 µm of 37 µm) — less than the feature model's own error against the
#: CAD rebuild (the −12 mm design, 0.13 % better on features, is 0.16 % worse rebuilt). Designs whose objectives
#: agree this closely count as the same optimum; a start that ends at a worse design still fails.
#: thesis_hub has a ridge along the pattern's phase: g_DIR hardly depends on it and g_FOV (a sum of per-pose minima
#: over the holes) has two local maxima there, at −0.477 and −0.531 rad, whose max-min values (rebuilt) differ by
#: 1.3e-6 relative; which one the CAD trust-region loop ends in is decided by its path, and with it by round-off
#: (issue 32 item 8: the same start gives −0.531 under the Haswell BLAS kernels, −0.477 under SkylakeX and Prescott).
PLATEAU_TOL = 3e-3


def _data(name: str) -> dict:
    data = tomllib.loads((STUDIES / f"{name}.toml").read_text())
    data["study"]["part"] = str((STUDIES / data["study"]["part"]).resolve())
    return data


def _with_defaults(data: dict, values: dict[str, float], folder: Path) -> dict:
    """The study pointing at a copy of its part script whose design variables default to ``values`` (a study's own
    ``start`` for them is dropped: the copied defaults are the start)."""
    part = Path(data["study"]["part"])
    copy_ = folder / part.name
    overrides = "\n".join(f"PARAMETERS[{k!r}]['default'] = {v!r}" for k, v in values.items())
    copy_.write_text(part.read_text() + "\n" + overrides + "\n")
    out = copy.deepcopy(data)
    out["study"]["part"] = str(copy_)
    table = out["design"].get("parameters")
    if isinstance(table, dict):
        for spec in table.values():
            if isinstance(spec, dict):
                spec.pop("start", None)
    return out


def _optimum(setup, problem=None) -> tuple[np.ndarray, float, np.ndarray]:
    """(the optimum, its combined value, its raw objectives in their physical units) — for a nonlinear design map
    all three of the CAD rebuild, as the study reports them (``solve_with_cad``'s ``objectives_best``): the set-up's
    feature model is the map linearised at its anchor, wrong away from it (issue 32 item 8: on thesis_hub, at two
    designs 0.05 rad of phase apart whose rebuilt objectives agree to 2e-6, the anchor's linearisation 0.5 rad
    away said g_FOV 0.209 and 0.240)."""
    problem = problem or setup.problem
    oc = setup.config.optimizer
    if setup.linear:
        res = optimise(problem, oc)
    else:
        res = solve_with_cad(problem, lambda x: setup.rebuild_holes(setup.rebuild_shape(x)), oc)
    assert not res.interrupted and res.feasible, res.message
    x = np.asarray(res.x_best, float)
    if setup.linear:
        g = np.asarray(problem.evaluate_batch(x[None])[0][0], float)
    else:
        g = np.array([res.objectives_best[name] for name in problem.names], float)
    return x, float(res.combined_best), g


def _other_starts(x0: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> list[np.ndarray]:
    return [x0 + TOWARDS * (lower + f * (upper - lower) - x0) for f in FRACTIONS]


def _feasible(setup, x: np.ndarray) -> bool:
    """Every kept requirement of the set-up's model holds at ``x``."""
    c, _, r = setup.model.features(x)
    return float(setup.problem.cset.stacked(c, r, x).min(initial=0.0)) >= -1e-9


def _same(found: list[tuple[np.ndarray, float, np.ndarray]], space) -> None:
    """The same optimum from every start: the same design (``X_TOL``) and combined value (``COMBINED_TOL``); or, on a
    plateau of the objective, designs whose objectives in their physical units agree to ``PLATEAU_TOL`` of
    themselves (equally good designs: the start picks among them, not a worse one)."""
    x_ref, c_ref, g_ref = found[0]
    for x, c, g in found[1:]:
        if np.all(np.abs(x - x_ref) <= X_TOL * space.span):
            assert c == pytest.approx(c_ref, rel=COMBINED_TOL, abs=COMBINED_TOL), (c, c_ref)
        else:
            assert g == pytest.approx(g_ref, rel=PLATEAU_TOL), (x, x_ref, g, g_ref)


def test_every_study_with_a_design_variable_is_covered():
    """Every study of studies/ has a design variable (the parametrised test below covers them all)."""
    assert ALL and all("design" in _data(n) for n in ALL)


@pytest.mark.parametrize("name", ALL)
def test_the_optimum_does_not_depend_on_the_start(name, tmp_path):
    data = _data(name)
    config = load_study(copy.deepcopy(data))
    found = []
    if config.study.part_kind == "step":
        reference = setup_study(config)
        space = reference.space
        for x0 in _other_starts(space.x0, space.lower, space.upper):
            assert _feasible(reference, x0), x0
            p = reference.problem
            problem = Problem(dataclasses.replace(space, x0=x0), p.model, p.camera, p.trajectory, p.T_task_part,
                              p.objective_config, p.constraint_config, p.fixed_mask,
                              occlusion_mesh=p.occlusion_mesh, feature_mask=p.feature_mask)
            found.append(_optimum(reference, problem))
    else:
        specs = [p for p in config.design.parameters if not p.is_int]
        names = [p.name for p in specs]
        lower, upper = np.array([p.lower for p in specs], float), np.array([p.upper for p in specs], float)
        x_default = np.array([p.default if p.start is None else p.start for p in specs], float)  # the study's start
        for k, x0 in enumerate(_other_starts(x_default, lower, upper)):
            folder = tmp_path / f"start{k}"
            folder.mkdir()
            setup = setup_study(load_study(_with_defaults(data, dict(zip(names, map(float, x0), strict=True)),
                                                          folder)))
            np.testing.assert_allclose(setup.space.x0, x0, rtol=0, atol=1e-12)  # the start really changed
            assert _feasible(setup, x0), x0
            found.append(_optimum(setup))
            space = setup.space
    _same(found, space)
