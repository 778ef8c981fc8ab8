"""CAD in the outer loop: the trust-region loop around the feature-model optimiser (DESIGN.md).

Round k: optimise on the current feature model inside the trust region (the whole box in round 1),
rebuild the candidate in CAD and re-extract its holes, match them to the prediction by geometry, and
compare (centres and radii, ``tol_mm``, default 1e-6 mm). Agreement ends the loop: the answer is the
real CAD rebuild — unless failed rebuilds had cut the region short: then the search goes on from the agreeing
design in a smaller region (towards the failed designs) for the remaining rounds, keeping the best.
Otherwise the map is refreshed (linearised again) at the rebuilt point, which becomes the new centre
unless its true (re-extracted) combined objective is worse than the centre's — then the region shrinks
around the centre. The best CAD-evaluated design (feasible first) is kept throughout and returned
if no round agrees within ``max_rounds``. A rebuild that raises (or times out, in the caller's
``rebuild``), also one of the map refresh's, is an infeasible point: the region shrinks around the centre.
The first centre is the feature model's anchor (``model.x0``), not the part's current values; the anchor,
built at set-up (the model's reference holes), also counts as a CAD-evaluated design, so it is returned when
no round's design builds or beats it; without such an anchor and with no successful rebuild,
``CadfeatError`` "no buildable design".

Ctrl-C in round 1 returns the best design on the feature model, marked interrupted (not yet verified);
later, the best verified design so far.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from cadfeat.cad.features import Hole, holes_to_arrays, match_holes
from cadfeat.design.design_space import LinearFeatureModel
from cadfeat.design.optimize import FEAS_TOL, OptimizerConfig, OptimResult, optimise
from cadfeat.errors import CadfeatError


def _predicted_holes(model: Any, x: np.ndarray) -> list[Hole]:
    c, a, r = model.features(x)
    return [dataclasses.replace(h, centre=c[i], axis=a[i], radius_mm=float(r[i])) for i, h in enumerate(model.holes)]


def _ordered(model: Any, x: np.ndarray, holes: list[Hole], match_tol_mm: float) -> tuple[list[Hole], float]:
    """Extracted ``holes`` in the model's order (matched to the prediction at x) and the largest error
    ‖Δcentre‖ + |Δradius| (mm)."""
    predicted = _predicted_holes(model, x)
    idx = match_holes(predicted, holes, tol_mm=match_tol_mm, axis_tol_rad=1e-3)
    ordered = [holes[i] for i in idx]
    c_p, _, r_p = holes_to_arrays(predicted)
    c_r, _, r_r = holes_to_arrays(ordered)
    err = float(np.max(np.linalg.norm(c_r - c_p, axis=1) + np.abs(r_r - r_p), initial=0.0))
    return ordered, err


def _anchor_candidate(problem: Any, x: np.ndarray) -> dict | None:
    """The feature model's anchor as a CAD-evaluated design: the set-up built it (the model's reference holes are
    its extracted holes), so it is the fallback when no round's design builds (issue 16: a failing region next to
    the anchor must not leave the loop without a buildable answer)."""
    holes = list(getattr(problem.model, "holes", []) or [])
    if not holes or not np.allclose(problem.model.features(x)[0], holes_to_arrays(holes)[0], atol=1e-9):
        return None
    c, a, r = holes_to_arrays(holes)
    g = problem.features_objectives(c, a, r, depth_mm=[float(h.depth_mm) for h in holes])
    cons = problem.features_constraints(c[None], r[None], g[None], np.asarray(x, float)[None])[0]
    violation = float(max(0.0, -cons.min(initial=0.0)))
    return {"x": np.asarray(x, float).copy(), "combined": float(problem.combined_from(g)),
            "objectives": dict(zip(problem.names, map(float, g), strict=True)), "feasible": violation <= FEAS_TOL,
            "violation": violation, "holes": holes}


def solve_with_cad(problem: Any, rebuild: Callable[[np.ndarray], list[Hole]], config: OptimizerConfig | None = None,
                   *, refresh: Callable[[np.ndarray, list[Hole]], Any] | None = None, max_rounds: int = 6,
                   tol_mm: float = 1e-6, match_tol_mm: float = 5.0, shrink: float = 0.5, fd_rel_step: float = 1e-4,
                   progress: Callable[[dict], None] | None = None) -> OptimResult:
    """Optimise ``problem`` on its feature model and verify with CAD (module docstring).

    ``rebuild(x) -> list[Hole]``: build the part at design x and extract its holes (any order; raising =
    infeasible). ``refresh(x, holes) -> FeatureModel``: the feature model linearised at x (``holes``: the
    extracted holes in model order); default ``LinearFeatureModel.from_rebuild`` with forward steps (backward at
    an upper bound, so every rebuild stays within the bounds) of ``fd_rel_step`` × each variable's range.
    Returns an ``OptimResult`` whose ``x_best`` is verified by CAD (unless interrupted in round 1 or no round
    agreed: see ``message``), ``holes`` the extracted holes (model order) and ``cad_rounds`` one dict per round."""
    config = config or OptimizerConfig()
    t0 = time.perf_counter()
    n0 = problem.n_evals
    space = problem.space
    history: list[dict] = []

    def default_refresh(x: np.ndarray, holes: list[Hole]) -> Any:
        steps = fd_rel_step * space.span
        steps = np.where(x + steps > space.upper, -steps, steps)  # backward at an upper bound: stay buildable
        return LinearFeatureModel.from_rebuild(rebuild, x, steps, holes0=holes,
                                               names=space.names, match_tol_mm=match_tol_mm)

    refresh = refresh or default_refresh
    prob = problem
    # the first centre of the trust region: the feature model's own anchor (a design that was built), not the
    # part's current values, so that a shrinking region does not depend on where the part started (issue 16)
    anchor = getattr(problem.model, "x0", None)
    x_c = space.x0.copy() if anchor is None or np.shape(anchor) != space.x0.shape else space.clip(anchor)
    centre_value: float | None = None
    radius: np.ndarray | None = None
    rounds: list[dict] = []
    verified: dict | None = _anchor_candidate(problem, x_c) if anchor is not None else None
    rebuilt = False  # whether a round's design has been rebuilt yet (an interrupt before: the feature optimum)
    agreed = 0  # the round whose rebuild agreed with the model, when failed rebuilds had cut the region short
    last: OptimResult | None = None

    def progress_all(entry: dict) -> None:
        history.append(entry)
        if progress is not None:
            progress(entry)

    def finish(res: OptimResult, interrupted: bool, message: str) -> OptimResult:
        res.history, res.cad_rounds = history, rounds
        res.interrupted = interrupted
        res.n_evals = problem.n_evals - n0
        res.time_s = time.perf_counter() - t0
        if verified is not None and (rebuilt or not interrupted):  # (interrupted before any rebuild: the feature
            res.x_best = verified["x"]                                # optimum, marked not verified)
            res.combined_best, res.f_best = verified["combined"], -verified["combined"]
            res.objectives_best = verified["objectives"]
            res.feasible, res.max_violation = verified["feasible"], verified["violation"]
            res.holes = verified["holes"]
        res.message = message
        return res

    for k in range(max_rounds):
        bounds = None if radius is None else (x_c - radius, x_c + radius)
        try:
            res = optimise(prob, config, progress_all, x_start=x_c, bounds=bounds)
        except KeyboardInterrupt:  # pragma: no cover - optimise catches it itself
            res = last
        if res is None or res.interrupted:
            if not rebuilt and res is not None:
                return finish(res, True, "interrupted in CAD round 1: best design on the feature model, "
                                         "not verified by a CAD rebuild")
            return finish(res or last, True, "interrupted: best CAD-verified design so far")
        last = res
        x_new = res.x_best
        entry: dict[str, Any] = {"round": k + 1, "x": x_new.tolist(), "predicted_combined": res.combined_best,
                                 "radius": None if radius is None else radius.tolist()}
        try:
            extracted = list(rebuild(x_new))
            holes, err = _ordered(prob.model, x_new, extracted, match_tol_mm)
        except KeyboardInterrupt:
            if not rebuilt:
                return finish(res, True, "interrupted in CAD round 1: best design on the feature model, "
                                         "not verified by a CAD rebuild")
            return finish(res, True, "interrupted: best CAD-verified design so far")
        except Exception as exc:  # noqa: BLE001 - a failing rebuild is an infeasible point
            entry.update(status="rebuild failed", error=f"{type(exc).__name__}: {exc}")
            rounds.append(entry)
            radius = shrink * (space.span if radius is None else radius)
            continue
        rebuilt = True
        c, a, r = holes_to_arrays(holes)
        g = prob.features_objectives(c, a, r, depth_mm=[float(h.depth_mm) for h in holes])
        cons = prob.features_constraints(c[None], r[None], g[None], x_new[None])[0]
        violation = float(max(0.0, -cons.min(initial=0.0)))
        combined = float(prob.combined_from(g))
        entry.update(status="agree" if err <= tol_mm else "differ", max_error_mm=err, true_combined=combined,
                     feasible=violation <= FEAS_TOL)
        rounds.append(entry)
        candidate = {"x": x_new.copy(), "combined": combined, "objectives": dict(zip(prob.names, map(float, g),
                                                                                      strict=True)),
                     "feasible": violation <= FEAS_TOL, "violation": violation, "holes": holes}
        if verified is None or (candidate["feasible"], combined) > (verified["feasible"], verified["combined"]):
            verified = candidate
        if err <= tol_mm:
            cut_short = radius is not None and any(r["status"] == "rebuild failed" for r in rounds)
            if not cut_short or k == max_rounds - 1:
                verified = candidate if not cut_short else verified
                return finish(res, False, f"CAD-verified in round {k + 1} (prediction error {err:.2g} mm)")
            # the region was cut short by failed rebuilds: the model is right here, so search on towards them from
            # this design in a smaller region (the best CAD-evaluated design is kept)
            agreed = k + 1
            if centre_value is None or combined >= centre_value:
                x_c, centre_value = x_new.copy(), combined
            radius = shrink * radius
            continue
        worse = centre_value is not None and combined < centre_value - 1e-9 * max(1.0, abs(centre_value))
        if worse:  # the model misled: keep the centre, trust a smaller region
            radius = shrink * (space.span if radius is None else radius)
        else:  # move on (a tiny violation from the model's error is corrected by the next, refreshed map)
            x_c, centre_value = x_new.copy(), combined
        try:
            prob = problem.with_model(refresh(x_new, holes))
        except KeyboardInterrupt:
            return finish(res, True, "interrupted: best CAD-verified design so far")
        except Exception as exc:  # noqa: BLE001 - a rebuild near x_new failed: keep the map, trust a smaller region
            entry["refresh_failed"] = f"{type(exc).__name__}: {exc}"
            radius = shrink * (space.span if radius is None else radius)
            continue
        entry["refreshed_at"] = x_new.tolist()
    if last is None or verified is None:
        failed = "; ".join(r.get("error", "") for r in rounds if r.get("error"))[:300]
        raise CadfeatError(f"no buildable design: every CAD rebuild the trust-region loop tried failed "
                           f"({len(rounds)} round(s); {failed or 'no design'})")
    if agreed:
        return finish(last, False, f"CAD-verified in round {agreed}; the search went on towards the designs that did "
                                   "not build: best CAD-evaluated design returned")
    return finish(last, False, f"no agreement between the feature model and CAD after {max_rounds} rounds: best "
                               "CAD-evaluated design returned")
