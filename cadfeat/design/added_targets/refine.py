"""Joint continuous refinement of the added holes and the study's movable holes after the greedy choice
(issue 31).

The greedy choice puts the added holes on the grid of candidate sites, beside the move-only optimum's holes. A
compass search then moves both: at each iteration every added hole is tried ``step`` mm along ± each of its face's
axes, and every position variable of the study (``Movable``: the movable holes' centres as functions of the design
vector x, from the study's feature model) ± ``step`` mm — all trial designs evaluated in ONE batched prediction,
the moved rims' hidden fractions from one exact ray test — the best feasible improving move is taken, and the
step halves when none improves, down to ``min_step_mm``. A trial is feasible when the study's own 2-D
requirements and bounds hold at its x (``Movable.feasible``), and every added hole keeps the requirements of
``sites.site_margins`` against the part's holes where they then are, and the ligament to the other added holes
on its face.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from cadfeat.cad.features import FaceOutline
from cadfeat.design.added_targets.objective import TargetObjective
from cadfeat.design.added_targets.sites import FaceRules, site_margins

__all__ = ["Movable", "Refined", "refine"]

Occlude = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""Rim hidden fraction (L, n) of n holes at centres (n, 3), axes (n, 3), rim radii (n,), through (n,), depth (n,)
mm (the exact ray test on the part)."""

_DIRECTIONS = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])


@dataclass(frozen=True)
class Movable:
    """The study's movable holes as functions of its design vector x (P,): the delivered ``x0``, the ``index`` of
    the position variables the refinement moves (mm), ``holes(X (T, P)) -> (centres (T, N0, 3), axes, rim radii
    (T, N0))`` (equal to the part's holes at x0), ``feasible(X) -> (T,) bool`` (bounds and the study's 2-D
    requirements) and ``moving`` (N0,) the holes a variable moves."""

    x0: np.ndarray
    index: np.ndarray
    holes: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
    feasible: Callable[[np.ndarray], np.ndarray]
    moving: np.ndarray


@dataclass
class Refined:
    """The refined added holes — face coordinates (k, 2) mm, rim centres (k, 3) mm, hidden fractions (L, k) —, the
    design vector x (P,) (None without ``Movable``), g_POSE before and after, the moves taken, designs evaluated."""

    uv: np.ndarray
    centres: np.ndarray
    occlusion: np.ndarray
    x: np.ndarray | None
    value_before: float
    value: float
    moves: int
    evaluations: int


@dataclass
class _State:
    """The current design: added holes (uv, centres, axes, occlusion), x, the part's holes and their occlusion."""

    uv: np.ndarray
    centres: np.ndarray
    axes: np.ndarray
    occ: np.ndarray
    x: np.ndarray | None
    base: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _rules_at(rules: Sequence[FaceRules], c: np.ndarray, a: np.ndarray, r: np.ndarray) -> list[FaceRules]:
    """Each face's rules with the part's holes where they are (rim centres c (N0, 3), axes, radii): the holes
    whose rim lies on the face's plane."""
    out: list[FaceRules] = []
    for rule in rules:
        o = rule.outline
        on = (np.abs((c - o.origin) @ o.normal) < 1e-4) & (a @ o.normal > 1 - 1e-6)
        out.append(dataclasses.replace(rule, hole_centres=c[on], hole_radii=r[on]))
    return out


def _added_ok(uv: np.ndarray, hole: int, faces: np.ndarray, rules: Sequence[FaceRules], all_uv: np.ndarray,
              rim_radius_mm: float) -> np.ndarray:
    """(T,) bool: trial places ``uv`` (T, 2) of added hole ``hole`` keep every requirement of its face and the
    ligament to the other added holes on that face (their places ``all_uv`` (k, 2))."""
    r = rules[int(faces[hole])]
    ok = np.min(np.stack(list(site_margins(uv, r).values())), axis=0) >= 0
    others = [j for j in range(len(faces)) if j != hole and faces[j] == faces[hole]]
    if others:
        gap = np.linalg.norm(uv[:, None] - all_uv[others][None], axis=-1).min(axis=1)
        ok &= gap >= 2 * rim_radius_mm + r.ligament_mm
    return ok


Moves = list[tuple[int, np.ndarray]]
"""Moves of the added holes: (which hole, its new face coordinates (2,) mm)."""


def _added_trials(st: _State, step: float, faces: np.ndarray, rules: Sequence[FaceRules],
                  outlines: list[FaceOutline], objective: TargetObjective, occlude: Occlude
                  ) -> tuple[Moves, np.ndarray, np.ndarray, np.ndarray]:
    """The feasible moves of the added holes: (moves (hole, uv), centres (T, k, 3), occlusion (T, L, k), base)."""
    k = len(st.uv)
    none: Moves = []
    if k == 0:
        return none, np.zeros((0, 0, 3)), np.zeros((0,) + st.occ.shape), np.zeros(0)
    face_rules = _rules_at(rules, st.base[0], st.base[1], st.base[2])
    trial = st.uv[:, None] + step * _DIRECTIONS[None]                                  # (k, 4, 2)
    ok = np.stack([_added_ok(trial[i], i, faces, face_rules, st.uv, objective.rim_radius_mm) for i in range(k)])
    who, way = np.nonzero(ok)
    if not who.size:
        return none, np.zeros((0, k, 3)), np.zeros((0,) + st.occ.shape), np.zeros(0)
    moved = np.stack([outlines[i].to_3d(trial[i, w]) for i, w in zip(who, way, strict=True)])
    n = len(who)
    hidden = occlude(moved, st.axes[who], np.full(n, objective.rim_radius_mm), np.zeros(n, bool),
                     np.full(n, objective.depth_mm))                                   # (L, T)
    C = np.broadcast_to(st.centres, (n, k, 3)).copy()
    C[np.arange(n), who] = moved
    O = np.broadcast_to(st.occ, (n,) + st.occ.shape).copy()
    O[np.arange(n), :, who] = hidden.T
    moves = [(int(i), trial[i, w]) for i, w in zip(who, way, strict=True)]
    return moves, C, O, np.arange(n)


def _variable_trials(st: _State, step: float, movable: Movable, faces: np.ndarray, rules: Sequence[FaceRules],
                     objective: TargetObjective, occlude: Occlude) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """The feasible moves of the position variables (± ``step`` each): (X (T, P), the part's holes there:
    centres, axes, radii, occlusion (T, L, N0))."""
    assert st.x is not None
    p = len(movable.index)
    X = np.repeat(st.x[None], 2 * p, axis=0)
    X[np.arange(2 * p), np.repeat(movable.index, 2)] += np.tile([step, -step], p)
    ok = movable.feasible(X)
    c, a, r = movable.holes(X)
    for t in np.flatnonzero(ok):  # the added holes keep their requirements against the moved holes (≤ 2p trials)
        face_rules = _rules_at(rules, c[t], a[t], r[t])
        ok[t] = all(_added_ok(st.uv[i:i + 1], i, faces, face_rules, st.uv, objective.rim_radius_mm)[0]
                    for i in range(len(st.uv)))
    X, c, a, r = X[ok], c[ok], a[ok], r[ok]
    occ = np.broadcast_to(st.base[3], (len(X),) + st.base[3].shape).copy()
    m = np.flatnonzero(movable.moving)
    if len(X) and m.size:
        through, depth = objective.base[3], objective.base[4]
        hidden = occlude(c[:, m].reshape(-1, 3), a[:, m].reshape(-1, 3), r[:, m].reshape(-1),
                         np.tile(through[m], len(X)), np.tile(depth[m], len(X)))          # (L, T·m)
        occ[:, :, m] = np.moveaxis(hidden.reshape(hidden.shape[0], len(X), m.size), 1, 0)
    return X, (c, a, r, occ)


def refine(objective: TargetObjective, rules: Sequence[FaceRules], faces: Sequence[int] | np.ndarray, uv0: np.ndarray,
           occlude: Occlude, step_mm: float, min_step_mm: float = 0.25, max_iterations: int = 40,
           movable: Movable | None = None) -> Refined:
    """Compass search of the added holes' face coordinates ``uv0`` (k, 2) on their faces (``faces`` (k,) indices
    into ``rules``) and, with ``movable``, of the study's position variables, from ``step_mm`` down to
    ``min_step_mm`` (module docstring)."""
    faces_a = np.asarray(faces, int)
    outlines = [rules[int(f)].outline for f in faces_a]
    uv = np.asarray(uv0, float).copy()
    axes = np.stack([o.normal for o in outlines]).reshape(-1, 3)
    centres = np.stack([o.to_3d(p) for o, p in zip(outlines, uv, strict=True)]).reshape(-1, 3)
    occ = occlude(centres, axes, np.full(len(uv), objective.rim_radius_mm), np.zeros(len(uv), bool),
                  np.full(len(uv), objective.depth_mm))
    base = objective._base(1)  # pyright: ignore[reportPrivateUsage]
    st = _State(uv, centres, axes, occ, None if movable is None else np.asarray(movable.x0, float).copy(),
                tuple(b[0].copy() for b in base))  # type: ignore[arg-type]
    g0 = g = float(objective.at(centres[None], axes[None], occ[None])[0])
    evaluations, moves, step = 1, 0, float(step_mm)
    for _ in range(max_iterations):
        if step < min_step_mm:
            break
        best = _best_move(st, step, objective, rules, faces_a, outlines, occlude, movable)
        evaluations += best[0]
        if best[1] is None or best[2] <= g + 1e-12:
            step /= 2
            continue
        best[1](st)
        g, moves = best[2], moves + 1
    return Refined(st.uv, st.centres, st.occ, st.x, g0, g, moves, evaluations)


def _best_move(st: _State, step: float, objective: TargetObjective, rules: Sequence[FaceRules], faces: np.ndarray,
               outlines: list[FaceOutline], occlude: Occlude, movable: Movable | None
               ) -> tuple[int, Callable[[_State], None] | None, float]:
    """(designs evaluated, the best feasible move as a function applying it to the state, its g_POSE)."""
    moves, C, O, _ = _added_trials(st, step, faces, rules, outlines, objective, occlude)
    T = len(moves)
    k = len(st.uv)
    Cs, Os = [C], [O]
    bases = [tuple(np.broadcast_to(b, (T,) + b.shape) for b in st.base)]
    X = np.zeros((0, 0))
    if movable is not None and len(movable.index):
        X, base_v = _variable_trials(st, step, movable, faces, rules, objective, occlude)
        Cs.append(np.broadcast_to(st.centres, (len(X), k, 3)))
        Os.append(np.broadcast_to(st.occ, (len(X),) + st.occ.shape))
        bases.append(base_v)
    n = T + len(X)
    if n == 0:
        return 0, None, -np.inf
    base = tuple(np.concatenate([b[i] for b in bases]) for i in range(4))
    values = objective.at(np.concatenate(Cs), np.broadcast_to(st.axes, (n, k, 3)), np.concatenate(Os), base)
    i = int(np.argmax(values))
    if i < T:
        hole, uv = moves[i]
        centre, occ_col = C[i, hole], O[i, :, hole]

        def apply(s: _State) -> None:
            s.uv[hole], s.centres[hole], s.occ[:, hole] = uv, centre, occ_col
        return n, apply, float(values[i])
    j = i - T
    chosen = (X[j].copy(), tuple(b[i].copy() for b in base))

    def apply_x(s: _State) -> None:
        s.x, s.base = chosen[0], chosen[1]  # type: ignore[assignment]
    return n, apply_x, float(values[i])
