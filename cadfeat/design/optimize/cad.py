"""CAD in the outer loop: the trust-region loop around the feature-model optimiser (docs/design.md "Data flow").

Round k: optimise on the current feature model inside the trust region (the whole box in round 1),
rebuild the candidate in CAD and re-extract its holes, match them to the prediction by geometry, and
compare (centres and radii, ``tol_mm``, default 1e-6 mm). Agreement ends the loop: the answer is the
real CAD rebuild — unless failed rebuilds had cut the region short: then the search goes on from the agreeing
design in a smaller region (towards the failed designs) for the remaining rounds, keeping the best.
Otherwise the map is refreshed (linearised again) at the rebuilt point, which becomes the new centre
unless its true (re-extracted) combined objective is worse than the centre's — then the region shrinks
around the centre. The best CAD-evaluated design (feasible first) is kept throughout and returned
if no round agrees within ``max_rounds``. A rebuild that raises (or times out, in the caller's
``rebuild``), also one of the map refresh's, is an infeasible point: the region shrinks around the centre. So is
a rebuild whose holes differ in number from the model's (a moved hole broke into an edge or into another hole).
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
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from cadfeat.cad.features import Hole, holes_to_arrays, match_holes
from cadfeat.design.design_space import FeatureModel, LinearFeatureModel
from cadfeat.design.optimize import FEAS_TOL, OptimizerConfig, OptimResult, optimise
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.design.optimize.evaluator import CadProblem, CadRound, HistoryEntry


def _predicted_holes(model: FeatureModel, x: np.ndarray) -> list[Hole]:
    c, a, r = model.features(x)
    return [dataclasses.replace(h, centre=c[i], axis=a[i], radius_mm=float(r[i])) for i, h in enumerate(model.holes)]


def _ordered(model: FeatureModel, x: np.ndarray, holes: list[Hole], match_tol_mm: float) -> tuple[list[Hole], float]:
    """Extracted ``holes`` in the model's order (matched to the prediction at x) and the largest error
    ‖Δcentre‖ + |Δradius| (mm)."""
    predicted = _predicted_holes(model, x)
    if len(holes) != len(predicted):  # (match_holes would pair a subset of extra holes)
        raise CadfeatError(f"CAD rebuild: {len(holes)} holes found, {len(predicted)} designed")
    idx = match_holes(predicted, holes, tol_mm=match_tol_mm, axis_tol_rad=1e-3)
    ordered = [holes[int(i)] for i in idx]
    c_p, _, r_p = holes_to_arrays(predicted)
    c_r, _, r_r = holes_to_arrays(ordered)
    err = float(np.max(np.linalg.norm(c_r - c_p, axis=1) + np.abs(r_r - r_p), initial=0.0))
    return ordered, err


class Candidate(TypedDict):
    """A CAD-evaluated design (``_candidate``)."""

    x: np.ndarray
    combined: float
    objectives: dict[str, float]
    feasible: bool
    violation: float
    holes: list[Hole]


def _candidate(problem: CadProblem, x: np.ndarray, holes: list[Hole]) -> Candidate:
    """A CAD-evaluated design: ``x`` with its extracted ``holes`` (model order), its true combined objective,
    objectives, feasibility and largest constraint violation."""
    c, a, r = holes_to_arrays(holes)
    g = problem.features_objectives(c, a, r, depth_mm=[float(h.depth_mm) for h in holes])
    cons = problem.features_constraints(c[None], r[None], g[None], x[None])[0]
    violation = float(max(0.0, -cons.min(initial=0.0)))
    return {"x": x.copy(), "combined": float(problem.combined_from(g)),
            "objectives": dict(zip(problem.names, map(float, g), strict=True)), "feasible": violation <= FEAS_TOL,
            "violation": violation, "holes": holes}


def _anchor_candidate(problem: CadProblem, x: np.ndarray) -> Candidate | None:
    """The feature model's anchor as a CAD-evaluated design: the set-up built it (the model's reference holes are
    its extracted holes), so it is the fallback when no round's design builds (issue 16: a failing region next to
    the anchor must not leave the loop without a buildable answer)."""
    holes = list(getattr(problem.model, "holes", []) or [])
    if not holes or not np.allclose(problem.model.features(x)[0], holes_to_arrays(holes)[0], atol=1e-9):
        return None
    return _candidate(problem, np.asarray(x, float), holes)


_FEATURE_OPTIMUM = "interrupted in CAD round 1: best design on the feature model, not verified by a CAD rebuild"
_BEST_VERIFIED = "interrupted: best CAD-verified design so far"


class _TrustRegionLoop:
    """The state of ``solve_with_cad``'s trust-region loop (module docstring): the centre ``x_c`` and its true
    combined objective, the region's half-widths ``radius`` (None: the whole box), the feature model ``prob``
    (refreshed each round), the rounds so far and the best CAD-evaluated design ``verified``."""

    def __init__(self, problem: CadProblem, rebuild: Callable[[np.ndarray], list[Hole]], config: OptimizerConfig,
                 refresh: Callable[[np.ndarray, list[Hole]], FeatureModel] | None, *, max_rounds: int, tol_mm: float,
                 match_tol_mm: float, shrink: float, fd_rel_step: float,
                 progress: Callable[[HistoryEntry], None] | None) -> None:
        self.t0 = time.perf_counter()
        self.n0 = problem.n_evals
        self.problem, self.rebuild, self.config, self.progress = problem, rebuild, config, progress
        self.max_rounds, self.tol_mm, self.match_tol_mm = max_rounds, tol_mm, match_tol_mm
        self.shrink, self.fd_rel_step = shrink, fd_rel_step
        self.space = problem.space
        self.history: list[HistoryEntry] = []
        self.refresh = refresh or self._default_refresh
        self.prob = problem
        # the first centre of the trust region: the feature model's own anchor (a design that was built), not the
        # part's current values, so that a shrinking region does not depend on where the part started (issue 16)
        anchor = getattr(problem.model, "x0", None)
        space = self.space
        self.x_c = space.x0.copy() if anchor is None or np.shape(anchor) != space.x0.shape else space.clip(anchor)
        self.centre_value: float | None = None
        self.radius: np.ndarray | None = None
        self.rounds: list[CadRound] = []
        self.verified: Candidate | None = _anchor_candidate(problem, self.x_c) if anchor is not None else None
        self.rebuilt = False  # whether a round's design has been rebuilt yet (an interrupt before: the feature optimum)
        self.agreed = 0  # the round whose rebuild agreed with the model, when failed rebuilds had cut the region short
        self.last: OptimResult | None = None

    def _default_refresh(self, x: np.ndarray, holes: list[Hole]) -> FeatureModel:
        steps = self.fd_rel_step * self.space.span
        steps = np.where(x + steps > self.space.upper, -steps, steps)  # backward at an upper bound: stay buildable
        return LinearFeatureModel.from_rebuild(self.rebuild, x, steps, holes0=holes,
                                               names=self.space.names, match_tol_mm=self.match_tol_mm)

    def _progress_all(self, entry: HistoryEntry) -> None:
        self.history.append(entry)
        if self.progress is not None:
            self.progress(entry)

    def _finish(self, res: OptimResult, interrupted: bool, message: str) -> OptimResult:
        res.history, res.cad_rounds = self.history, self.rounds
        res.interrupted = interrupted
        res.n_evals = self.problem.n_evals - self.n0
        res.time_s = time.perf_counter() - self.t0
        verified = self.verified
        if verified is not None and (self.rebuilt or not interrupted):  # (interrupted before any rebuild: the
            res.x_best = verified["x"]                                     # feature optimum, marked not verified)
            res.combined_best, res.f_best = verified["combined"], -verified["combined"]
            res.objectives_best = verified["objectives"]
            res.feasible, res.max_violation = verified["feasible"], verified["violation"]
            res.holes = verified["holes"]
        res.message = message
        return res

    def _shrink_region(self) -> None:
        """Trust a smaller region around the centre (``shrink`` × the current one; the whole box at first)."""
        self.radius = self.shrink * (self.space.span if self.radius is None else self.radius)

    def run(self) -> OptimResult:
        """All rounds; the result when one ends the loop, else the best CAD-evaluated design."""
        for k in range(self.max_rounds):
            done = self._round(k)
            if done is not None:
                return done
        last, verified = self.last, self.verified
        if last is None or verified is None:
            failed = "; ".join(r.get("error", "") for r in self.rounds if r.get("error"))[:300]
            raise CadfeatError(f"no buildable design: every CAD rebuild the trust-region loop tried failed "
                               f"({len(self.rounds)} round(s); {failed or 'no design'})")
        if self.agreed:
            return self._finish(last, False, f"CAD-verified in round {self.agreed}; the search went on towards the "
                                             "designs that did not build: best CAD-evaluated design returned")
        return self._finish(last, False, f"no agreement between the feature model and CAD after {self.max_rounds} "
                                         "rounds: best CAD-evaluated design returned")

    def _round(self, k: int) -> OptimResult | None:
        """Round k + 1: optimise in the region, rebuild, compare; the result if the loop ends here, else None."""
        radius = self.radius
        bounds = None if radius is None else (self.x_c - radius, self.x_c + radius)
        try:
            res = optimise(self.prob, self.config, self._progress_all, x_start=self.x_c, bounds=bounds)
        except KeyboardInterrupt:  # pragma: no cover - optimise catches it itself
            res = self.last
        if res is None or res.interrupted:
            if not self.rebuilt and res is not None:
                return self._finish(res, True, _FEATURE_OPTIMUM)
            last = res or self.last
            assert last is not None  # (optimise returns a result, interrupted or not)
            return self._finish(last, True, _BEST_VERIFIED)
        self.last = res
        x_new = res.x_best
        entry: CadRound = {"round": k + 1, "x": x_new.tolist(), "predicted_combined": res.combined_best,
                           "radius": None if radius is None else radius.tolist()}
        try:
            extracted = list(self.rebuild(x_new))
            holes, err = _ordered(self.prob.model, x_new, extracted, self.match_tol_mm)
        except KeyboardInterrupt:
            return self._finish(res, True, _BEST_VERIFIED if self.rebuilt else _FEATURE_OPTIMUM)
        except Exception as exc:  # noqa: BLE001 - a failing rebuild is an infeasible point
            entry.update(status="rebuild failed", error=f"{type(exc).__name__}: {exc}")
            self.rounds.append(entry)
            self._shrink_region()
            return None
        self.rebuilt = True
        candidate = _candidate(self.prob, x_new, holes)
        entry.update(status="agree" if err <= self.tol_mm else "differ", max_error_mm=err,
                     true_combined=candidate["combined"], feasible=candidate["feasible"])
        self.rounds.append(entry)
        verified = self.verified
        if verified is None or (candidate["feasible"], candidate["combined"]) > (verified["feasible"],
                                                                                 verified["combined"]):
            self.verified = candidate
        if err <= self.tol_mm:
            return self._agree(k, res, candidate, err)
        return self._move(res, candidate["combined"], holes, entry)

    def _agree(self, k: int, res: OptimResult, candidate: Candidate, err: float) -> OptimResult | None:
        """The rebuild agreed with the model: the answer, unless failed rebuilds had cut the region short."""
        cut_short = self.radius is not None and any(r.get("status") == "rebuild failed" for r in self.rounds)
        if not cut_short or k == self.max_rounds - 1:
            self.verified = candidate if not cut_short else self.verified
            return self._finish(res, False, f"CAD-verified in round {k + 1} (prediction error {err:.2g} mm)")
        # the region was cut short by failed rebuilds: the model is right here, so search on towards them from
        # this design in a smaller region (the best CAD-evaluated design is kept)
        self.agreed = k + 1
        combined = candidate["combined"]
        if self.centre_value is None or combined >= self.centre_value:
            self.x_c, self.centre_value = res.x_best.copy(), combined
        self._shrink_region()
        return None

    def _move(self, res: OptimResult, combined: float, holes: list[Hole], entry: CadRound) -> OptimResult | None:
        """The rebuild differed from the model: move the centre there (or shrink the region if it is worse) and
        refresh the map at the rebuilt point; the result if interrupted, else None."""
        x_new = res.x_best
        centre_value = self.centre_value
        worse = centre_value is not None and combined < centre_value - 1e-9 * max(1.0, abs(centre_value))
        if worse:  # the model misled: keep the centre, trust a smaller region
            self._shrink_region()
        else:  # move on (a tiny violation from the model's error is corrected by the next, refreshed map)
            self.x_c, self.centre_value = x_new.copy(), combined
        try:
            self.prob = self.problem.with_model(self.refresh(x_new, holes))
        except KeyboardInterrupt:
            return self._finish(res, True, _BEST_VERIFIED)
        except Exception as exc:  # noqa: BLE001 - a rebuild near x_new failed: keep the map, trust a smaller region
            entry["refresh_failed"] = f"{type(exc).__name__}: {exc}"
            self._shrink_region()
            return None
        entry["refreshed_at"] = x_new.tolist()
        return None


#: How far (mm) a rebuilt hole may lie from the feature model's prediction and still pair with it: the model of a
#: part whose map is not linear (a bolt circle turned by its phase) predicts away from its linearisation point only
#: approximately.
MATCH_TOL_MM = 5.0


def solve_with_cad(problem: CadProblem, rebuild: Callable[[np.ndarray], list[Hole]],
                   config: OptimizerConfig | None = None,
                   *, refresh: Callable[[np.ndarray, list[Hole]], FeatureModel] | None = None, max_rounds: int = 6,
                   tol_mm: float = 1e-6, match_tol_mm: float = MATCH_TOL_MM, shrink: float = 0.5,
                   fd_rel_step: float = 1e-4, progress: Callable[[HistoryEntry], None] | None = None) -> OptimResult:
    """Optimise ``problem`` on its feature model and verify with CAD (module docstring).

    ``rebuild(x) -> list[Hole]``: build the part at design x and extract its holes (any order; raising =
    infeasible). ``refresh(x, holes) -> FeatureModel``: the feature model linearised at x (``holes``: the
    extracted holes in model order); default ``LinearFeatureModel.from_rebuild`` with forward steps (backward at
    an upper bound, so every rebuild stays within the bounds) of ``fd_rel_step`` × each variable's range.
    Returns an ``OptimResult`` whose ``x_best`` is verified by CAD (unless interrupted in round 1 or no round
    agreed: see ``message``), ``holes`` the extracted holes (model order) and ``cad_rounds`` one dict per round."""
    loop = _TrustRegionLoop(problem, rebuild, config or OptimizerConfig(), refresh, max_rounds=max_rounds,
                            tol_mm=tol_mm, match_tol_mm=match_tol_mm, shrink=shrink, fd_rel_step=fd_rel_step,
                            progress=progress)
    return loop.run()
