"""The optimisation problem: design variables → features → measures → objectives and constraint margins.

``Problem`` ties a ``DesignSpace``, a ``FeatureModel``, a camera, a trajectory and the part pose to the
objective and constraint configurations. Everything the solvers need comes from one batched call,
``evaluate_batch(X (B,P)) -> (G (B,K) raw objectives, C (B,M) margins)``; the scalar helpers
(``objective``, ``constraints``...) are thin wrappers. Constraint margins are the 2-D kept requirements
(``constraints.ConstraintSet``) followed, for ``combine="constraint"``, by the measure thresholds
(g_i − threshold_i)/scale_i.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, TypeAlias

import numpy as np

from cadfeat import measures
from cadfeat.cell import Cell
from cadfeat.design.constraints import ConstraintConfig, ConstraintSet
from cadfeat.design.design_space import DesignSpace, FeatureModel
from cadfeat.design.hole_form import design_depths
from cadfeat.design.memory import DEPTH_GRID, check_fits, chunked, design_bytes
from cadfeat.design.objectives import (
    MEASURES,
    POSE_UNOBSERVABLE_MM,
    Normaliser,
    ObjectiveConfig,
    aggregate,
    combine,
    combined_indices,
    leximin_key,
    natural_units,
    per_pose_values,
)
from cadfeat.design.optimize import OptimizerConfig, optimise
from cadfeat.design.optimize.solvers import sobol_starts
from cadfeat.design.pose_terms import pose_aggregate_batch, pose_values, stacked_information
from cadfeat.design.unseen import scored_measures
from cadfeat.errors import CadfeatError
from cadfeat.measures.depth import DepthMaps
from cadfeat.measures.jacobian import diagnostics_from_gram
from cadfeat.measures.resolvability import resolvability_from_parts, scale_jacobian, scale_screws
from cadfeat.poses import cam_from_part

if TYPE_CHECKING:  # pragma: no cover
    from collections.abc import Mapping, Sequence

    import trimesh
    from numpy.typing import ArrayLike

    from cadfeat.camera import Camera
    from cadfeat.design.unseen import ScoredMeasures
    from cadfeat.measures.glare import GlareMaps
    from cadfeat.trajectory import Trajectory

__all__ = ["Problem"]


def _resolvability(J: np.ndarray, screws: np.ndarray, rotation_length_mm: float) -> np.ndarray:
    """``measures.resolvability`` (eq. 4.27–4.32) of stacked Jacobians J (M, 2N, 6), with the Gram matrices
    JᵀJ formed by one batched matmul (as ``measures.evaluate`` does) — same formula and helpers."""
    Js = scale_jacobian(J, rotation_length_mm)
    diag = diagnostics_from_gram(np.swapaxes(Js, 1, 2) @ Js)
    image_speed = np.linalg.norm((J @ screws[:, :, None])[..., 0], axis=-1)
    return resolvability_from_parts(Js, image_speed, scale_screws(screws, rotation_length_mm), diag["singular"],
                                    diag["sigma_min"])


PoseArray: TypeAlias = "np.ndarray | tuple[np.ndarray, ...]"
"""One entry of ``Problem.pose_arrays``: a measure's (B, L, N) or Λ's (B, L) values, or g_POSE's (errors (B, L) mm,
information (B, L, 6, 6))."""


class _Arrays:
    """Measures-like attribute access to a dict of arrays."""

    def __init__(self, arrays: Mapping[str, object]):
        self.__dict__.update(arrays)


class _BatchPose:
    """g_POSE's per-pose predicted errors (..., L) mm and aggregated value (...,) (``design.pose_terms``), read
    by ``objectives.per_pose_values`` as ``measures.pose``."""

    def __init__(self, errors_mm: np.ndarray, g: np.ndarray):
        self.errors_mm, self.g = errors_mm, g

    def error_mm(self, rotation_length_mm: float | None = None) -> np.ndarray:
        return self.errors_mm


class _WithPose:
    """A ``Measures`` with ``pose`` attached (None when g_POSE is not chosen)."""

    def __init__(self, measures: object, pose: _BatchPose | None):
        self._m, self.pose = measures, pose

    def __getattr__(self, name: str) -> object:
        return getattr(self._m, name)


class Problem:
    """A feature-design problem (see module docstring).

    ``T_task_part`` (4,4) places the part in the task frame of ``trajectory`` (``T_task_cam`` poses);
    ``fixed_mask`` (N,) marks holes that may not move (kept out of the constraints that only concern
    moving holes). ``normaliser`` defaults to the objective config's ``normalisation``: for ``"payoff"``
    (default) the payoff table of the design space (``payoff_normaliser``), else ``Normaliser.build(method,
    g(x0), natural units at x0)``. ``feature_mask`` (N,) bool: the holes whose FOV/focus/resolution are scored
    (default: the movable ones, all when none moves). ``cell``: the robot cell g_POSE is predicted in (default
    ``Cell()``).
    """

    def __init__(self, space: DesignSpace, model: FeatureModel, camera: Camera, trajectory: Trajectory,
                 T_task_part: np.ndarray, objective_config: ObjectiveConfig, constraint_config: ConstraintConfig,
                 fixed_mask: ArrayLike | None = None, *, occlusion_mesh: trimesh.Trimesh | None = None,
                 normaliser: Normaliser | None = None, feature_mask: ArrayLike | None = None, cell: Cell | None = None):
        self.space = space
        self.cell = cell if cell is not None else Cell()
        """The robot cell (``cadfeat.cell.Cell``): g_POSE's models see its gate, placement and sensor noise."""
        self.model = model
        self.camera = camera
        self.trajectory = trajectory
        self.T_task_part = np.asarray(T_task_part, dtype=float)
        self.objective_config = objective_config
        self.constraint_config = constraint_config
        n = len(model.holes)
        self.fixed_mask = np.zeros(n, dtype=bool) if fixed_mask is None else np.asarray(fixed_mask, dtype=bool)
        self.occlusion_mesh = occlusion_mesh
        self._glare: GlareMaps | None = None  # at the nominal poses (set_glare), or None
        if feature_mask is not None:
            self.feature_mask = np.asarray(feature_mask, dtype=bool)
        else:
            self.feature_mask = ~self.fixed_mask if (~self.fixed_mask).any() else None
        self.T_cam_part = cam_from_part(trajectory.T_task_cam, self.T_task_part)
        self.screws = np.asarray(trajectory.velocity_screws(), dtype=float)
        # the volume requirement is relative to the part as it is (the start): its radii, not the map's anchor's

        check_fits(len(self.screws), n, occlusion=occlusion_mesh is not None, what="optimisation problem")
        self.cset = ConstraintSet(model.holes, constraint_config, self.fixed_mask,
                                  radii0=model.features(space.x0)[2],
                                  outline_rates=getattr(model, "outline_rates", None),
                                  x_anchor=getattr(model, "x0", None))
        self.names = objective_config.names
        self.n_evals = 0
        c0, _, _ = model.features(0.5 * (space.lower + space.upper))  # the box centre: not start-dependent
        depth = np.einsum("lij,nj->lni", self.T_cam_part[:, :3, :3], c0)[..., 2] + self.T_cam_part[:, None, 2, 3]
        self.units = natural_units(objective_config, camera, len(self.screws), n, float(np.median(depth)))
        self._unit_by_name = {MEASURES[m]: u for m, u in self.units.items()}
        self._normaliser = normaliser  # built on first use (``normaliser``): the payoff table costs solves
        keys = [ObjectiveConfig.key(nm) for nm in self.names]
        self._thr_idx = np.array([i for i, k in enumerate(keys) if k in objective_config.thresholds], dtype=int)
        self._thr = np.array([objective_config.thresholds[keys[i]] for i in self._thr_idx])

    @property
    def normaliser(self) -> Normaliser:
        """The objective scales (class docstring), built on first use."""
        if self._normaliser is None:
            cfg = self.objective_config
            if cfg.normalisation == "payoff":
                self._normaliser = self.payoff_normaliser(self._unit_by_name)
            else:
                g0 = self.features_objectives(*self.model.features(self.space.x0),
                                              depth_mm=self.hole_depths(self.space.x0[None]))
                method = "natural" if cfg.normalisation == "payoff" else cfg.normalisation
                self._normaliser = Normaliser.build(method, dict(zip(self.names, g0, strict=True)),
                                                    self._unit_by_name)
        return self._normaliser

    @property
    def normaliser_built(self) -> Normaliser | None:
        """The objective scales if they are built (given, or ``normaliser`` asked for), else None: never builds."""
        return self._normaliser

    @property
    def scales(self) -> np.ndarray:
        return np.array([self.normaliser.reference[n] for n in self.names])

    @property
    def offsets(self) -> np.ndarray:
        return np.array([self.normaliser.offset.get(n, 0.0) for n in self.names])

    @property
    def combined_idx(self) -> np.ndarray:
        """Indices of the objectives in the combination (``objectives.combined_indices``)."""
        return np.array(combined_indices(self.objective_config, self.names, self.normaliser.constant), dtype=int)

    def payoff_normaliser(self, unit_by_name: dict[str, float], samples: int = 32) -> Normaliser:
        """The ideal/nadir ``Normaliser`` of the payoff table (``Normaliser.from_payoff``): each objective
        maximised alone on features (multi-start from three scaled Sobol points of ``optimize.sobol_starts``
        and the design-space centre — never from the starting design), under the same 2-D constraints;
        plus ``samples`` fixed Sobol designs (those meeting the 2-D constraints) to tell an objective that does
        not depend on the design (constant) from non-conflicting ones. With one objective there is nothing to
        trade off: no solve — its table row is the best of those samples (ĝ = 1 there, 0 at the worst; the
        study's own solve finds the optimum, ĝ ≥ 1). A local solve there only moved the scale with whichever
        local optimum its few starts reached, so the reported ĝ of one optimum depended on the starting design."""
        cfg = self.objective_config
        natural = Normaliser.build("natural", dict.fromkeys(self.names, 1.0), unit_by_name)
        space = self.space
        centre = 0.5 * (space.lower + space.upper)
        if len(cfg.measures) == 1:
            return self._sampled_normaliser(natural, samples)
        table: list[np.ndarray] = []
        for m in cfg.measures:
            sub_cfg = cfg.replace(measures=(m,), combine="weighted", weights={}, thresholds={},
                              normalisation="natural")
            sub_norm = Normaliser.build("natural", {MEASURES[m]: 1.0}, unit_by_name)
            sub = Problem(replace(space, x0=centre), self.model, self.camera, self.trajectory, self.T_task_part,
                          sub_cfg, self.constraint_config, self.fixed_mask, occlusion_mesh=self.occlusion_mesh,
                          normaliser=sub_norm, feature_mask=self.feature_mask, cell=self.cell)
            sub._depth_maps = self.occlusion  # the same poses: share the depth maps
            sub._glare = self._glare
            res = optimise(sub, OptimizerConfig(method="multistart", starts=3, maxiter=60, seed=0,
                                                snap_standard_sizes=False), x_start=centre)
            table.append(res.x_best)
        X = np.vstack(table)
        G = self.batch_objectives(*self._features_batch(X), depth_mm=self.hole_depths(X))
        _, S = self._feasible_sample(samples)
        S = np.vstack([S, G])
        rng = np.ptp(S, axis=0)
        normaliser = Normaliser.from_payoff(self.names, G, natural.reference, rng, S.min(axis=0))
        assert normaliser.payoff is not None  # (from_payoff sets it)
        normaliser.payoff["designs"] = X.tolist()
        return normaliser

    def _feasible_sample(self, samples: int) -> tuple[np.ndarray, np.ndarray]:
        """The fixed Sobol designs (``samples`` of them, seed 12345) that keep the requirements, and their raw
        objectives: (designs (M, n), objectives (M, K))."""
        space = self.space
        XS = space.lower + sobol_starts(space.size, samples, 12345) * (space.upper - space.lower)
        c, a, r = self._features_batch(XS)
        S = self.batch_objectives(c, a, r, depth_mm=self.hole_depths(XS))
        feasible = self.cset.stacked(c, r, XS).min(axis=-1, initial=0.0) >= -1e-6  # the kept requirements hold
        return XS[feasible], S[feasible]

    def _sampled_normaliser(self, natural: Normaliser, samples: int) -> Normaliser:
        """``payoff_normaliser`` of a single objective: the payoff row is the best of the fixed Sobol designs that
        meet the 2-D constraints (the design-space centre if none does)."""
        XS, S = self._feasible_sample(samples)
        if not len(XS):
            XS = 0.5 * (self.space.lower + self.space.upper)[None]
            S = self.batch_objectives(*self._features_batch(XS), depth_mm=self.hole_depths(XS))
        best = int(np.argmax(S[:, 0]))
        normaliser = Normaliser.from_payoff(self.names, S[best:best + 1], natural.reference, np.ptp(S, axis=0),
                                            S.min(axis=0))
        assert normaliser.payoff is not None
        normaliser.payoff["designs"] = XS[best:best + 1].tolist()
        return replace(normaliser, note=normaliser.note.replace(
            "ideal/nadir from the payoff table: each objective maximised alone over the design space (on features)",
            f"one objective: ideal/nadir = the best/worst of {len(S)} fixed Sobol designs that keep the requirements "
            "(on features; no payoff solve: nothing to trade off, the study's solve finds the optimum, ĝ ≥ 1 there)"))

    def hole_depths(self, X: np.ndarray) -> np.ndarray | None:
        """(B, N) hole depths (mm) of designs X by the feature model (``design.hole_form``), None without rates."""
        return design_depths(self.model, X)

    def _features_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        centres, axes, radii = self.model.features_batch(np.atleast_2d(X))
        return centres, np.broadcast_to(axes, centres.shape), radii

    def normalised(self, G: np.ndarray) -> np.ndarray:
        """Normalised objectives ĝ = (g − offset)/scale (..., K) of raw objectives G (..., K)."""
        return (np.asarray(G, dtype=float) - self.offsets) / self.scales

    def leximin_key(self, G: np.ndarray) -> np.ndarray:
        """Sorted normalised combined objectives (..., K') of raw G: the max-min value first, then the
        next-worst, ... (``objectives.leximin_key``)."""
        return leximin_key(self.normalised(G)[..., self.combined_idx])

    def limiting(self, G: np.ndarray) -> str:
        """Name of the objective that limits a max-min value (the smallest normalised combined objective)."""
        Gn = self.normalised(G)[..., self.combined_idx]
        return self.names[int(self.combined_idx[int(np.argmin(Gn))])]

    # ------------------------------------------------------------------------------- single designs
    def with_model(self, model: FeatureModel) -> Problem:
        """The same problem on another feature model (same normaliser, so values stay comparable)."""
        other = Problem(self.space, model, self.camera, self.trajectory, self.T_task_part, self.objective_config,
                        self.constraint_config, self.fixed_mask, occlusion_mesh=self.occlusion_mesh,
                        normaliser=self.normaliser, feature_mask=self.feature_mask, cell=self.cell)
        other._depth_maps = getattr(self, "_depth_maps", None)
        other._glare = self._glare
        return other

    def set_glare(self, maps: GlareMaps | None) -> None:
        """g_POSE's glare maps (``measures.glare.GlareMaps`` at this problem's poses, ``render.glare.glare_maps``):
        a blind rim in a conductor is found as often as its contrast to the rendered face allows; None: off."""
        self._glare = maps

    @property
    def glare(self) -> GlareMaps | None:
        """The glare maps for this problem's poses (tiled when the poses are stacked copies of the trajectory,
        as ``occlusion``), or None."""
        maps = self._glare
        if maps is None:
            return None
        n = len(self.T_cam_part)
        if maps.n_poses != n and n % maps.n_poses == 0:
            return maps.tile(n // maps.n_poses)
        return maps

    def measures_from_features(self, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                               exact_occlusion: bool = False) -> ScoredMeasures:
        """``measures.evaluate`` of hole features (part frame) along the trajectory, as the objectives score them
        (``design.unseen.scored_measures``: the unseen-hole rule applied); occlusion by the optimiser's depth maps,
        or by the exact ray test against the mesh with ``exact_occlusion``."""
        cfg = self.objective_config
        if np.any(np.asarray(radii) <= 0):
            raise CadfeatError(f"a design gives a hole radius ≤ 0 mm: {np.asarray(radii).tolist()}")
        m = measures.evaluate(self.camera, self.T_cam_part, self.screws, centres, axes, radii,
                              min_axis_px=cfg.min_axis_px, rotation_length_mm=cfg.rotation_length_mm,
                              occlusion_mesh=self.occlusion_mesh if exact_occlusion else self.occlusion)
        return scored_measures(m, self.camera, cfg.min_axis_px)

    @property
    def occlusion(self) -> DepthMaps | None:
        """The optimiser's occlusion test: depth maps of ``occlusion_mesh`` at the trajectory's poses
        (``measures.depth.DepthMaps``, built once on first use), or None without a mesh."""
        if self.occlusion_mesh is None:
            return None
        if getattr(self, "_depth_maps", None) is None:
            check_fits(len(self.T_cam_part), len(self.model.holes), what="the optimiser's occlusion test")
            self._depth_maps = DepthMaps(self.occlusion_mesh, self.camera, self.T_cam_part, grid=DEPTH_GRID)
        maps = self._depth_maps
        n = len(self.T_cam_part)
        if maps.n_poses != n and n % maps.n_poses == 0:
            # poses stacked as S copies of the trajectory, each seen from a slightly displaced camera (the
            # robustness sampling): the nominal pose's depth map stands for its displaced copies
            return maps.tile(n // maps.n_poses)
        return maps

    def measures(self, x: np.ndarray) -> ScoredMeasures:
        return self.measures_from_features(*self.model.features(np.asarray(x, dtype=float)))

    def features_objectives(self, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                            exact_occlusion: bool = False, depth_mm: Sequence[float] | np.ndarray | None = None
                            ) -> np.ndarray:
        """Raw aggregated objectives (K,) in ``names`` order from hole features (``exact_occlusion``: as
        ``measures_from_features``; the reported before/after values use it); ``depth_mm`` (N,) the holes'
        depths for g_POSE (None: the reference holes')."""
        m = self.measures_from_features(centres, axes, radii, exact_occlusion)
        cfg = self.objective_config
        pose = None
        if "pose" in cfg.measures:  # g_POSE: pose information + pose_objective (``design.pose_terms``)

            g_pose, e = pose_values(self, centres[None], axes[None], radii[None], exact_occlusion,
                                    None if depth_mm is None else np.asarray(depth_mm, float).reshape(1, -1))
            pose = _BatchPose(-e[0], g_pose[0])
        values = per_pose_values(_WithPose(m, pose), cfg, self.feature_mask)
        return np.array([pose.g if k == "pose" and pose is not None else
                         aggregate(values[k], cfg.aggregate, cfg.smoothmin_beta, self.units[k])
                         for k in cfg.measures])

    def batch_objectives(self, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                         depth_mm: np.ndarray | None = None) -> np.ndarray:
        """Raw aggregated objectives (B, K) of B designs' features (B,N,3), (B,N,3), (B,N) and hole depths (B,N)
        mm (None: the reference holes'): ``_batch_objectives`` on chunks of designs within the memory budget
        (``cadfeat.design.memory``; one pass when they fit)."""
        B, N = np.shape(radii)
        axes = np.broadcast_to(axes, np.shape(centres))
        return chunked(lambda sl: self._batch_objectives(centres[sl], axes[sl], radii[sl],
                                                         None if depth_mm is None else depth_mm[sl]), B,
                       design_bytes(len(self.screws), N), "the optimiser's batched evaluation")

    def _batch_objectives(self, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                          depth_mm: np.ndarray | None = None) -> np.ndarray:
        """Raw aggregated objectives (B, K) of B designs' features (B,N,3), (B,N,3), (B,N) in one pass:
        ``pose_arrays`` aggregated over the poses (``aggregate_arrays``); ``depth_mm`` (B, N) the holes' depths
        (None: the reference holes'). Equal to ``features_objectives`` design by design (tested)."""
        return self.aggregate_arrays(self.pose_arrays(centres, axes, radii, depth_mm=depth_mm))

    def pose_arrays(self, centres: np.ndarray, axes: np.ndarray, radii: np.ndarray,
                    noise_grey: np.ndarray | None = None, depth_mm: np.ndarray | None = None
                    ) -> dict[str, PoseArray]:
        """Per-pose arrays of B designs at the problem's L poses: each chosen measure's (B, L, N) feature values
        (``seen``, the Jacobian rows' weights, for Λ), Λ as (B, L), and for g_POSE
        ``("pose", (errors (B, L) mm, information (B, L, 6, 6)))``.

        The per-feature measures come from ONE ``measures.evaluate`` call on the B·N features side by side
        (they are independent per feature); its per-pose Jacobian values mix designs and are not used.
        Instead Λ is computed per (design, pose) with ``measures.stacked_jacobian`` (each feature's rows
        weighted by ``seen``, the seen fraction of its rim, 0 where it cannot be seen, as ``evaluate`` does) and
        ``measures.resolvability`` on B·L stacked Jacobians. ``noise_grey`` (L, 1) or None: the sensor noise per
        pose of g_POSE's σ model."""
        cfg = self.objective_config
        B, N = radii.shape
        L = len(self.screws)
        if np.any(radii <= 0):
            raise CadfeatError(f"a design gives a hole radius ≤ 0 mm: {radii.min():g}")
        m = None if set(cfg.measures) == {"pose"} else \
            self.measures_from_features(centres.reshape(B * N, 3), axes.reshape(B * N, 3), radii.reshape(B * N))

        def per_design(a: np.ndarray) -> np.ndarray:  # (L, B·N) → (B, L, N)
            return np.moveaxis(a.reshape(L, B, N), 1, 0)
        attrs = {"fov": "fov" if cfg.fov_measure == "cone" else "fov_px", "focus": "focus",
                 "resolution": "resolution_px", "resolvability": "seen"}
        arrays: dict[str, PoseArray] = {attrs[k]: per_design(getattr(m, attrs[k])) for k in cfg.measures if k != "pose"}
        if "pose" in cfg.measures:  # g_POSE: one pose_information on the B·L stacked poses (``design.pose_terms``)

            info = stacked_information(self, centres, axes, radii, noise_grey, depth_mm)
            arrays["pose"] = (info.error_mm(cfg.pose_rotation_length_mm).reshape(B, L),
                              info.information.reshape(B, L, 6, 6))
        if "resolvability" in cfg.measures and B == 1 and m is not None:  # evaluate's own Λ is the design's
            arrays["resolvability"] = np.asarray(m.resolvability)[None]
        elif "resolvability" in cfg.measures:
            R, t = self.T_cam_part[:, :3, :3], self.T_cam_part[:, :3, 3]
            pts = centres[:, None] @ np.swapaxes(R, 1, 2)[None] + t[None, :, None, :]  # (B, L, N, 3)
            J = measures.stacked_jacobian(self.camera, pts.reshape(B * L, N, 3),
                                          np.asarray(arrays["seen"]).reshape(B * L, N))
            arrays["resolvability"] = _resolvability(J, np.tile(self.screws, (B, 1)),
                                                     cfg.rotation_length_mm).reshape(B, L)
        return arrays

    def aggregate_arrays(self, arrays: Mapping[str, PoseArray]) -> np.ndarray:
        """Raw aggregated objectives (B, K) of ``pose_arrays`` (any leading batch shape B of the (B, L, …) arrays)."""
        cfg = self.objective_config
        fields: dict[str, object] = dict(arrays)
        pose: _BatchPose | None = None
        if "pose" in arrays:
            e, info = arrays["pose"]
            g = pose_aggregate_batch(e, info, cfg.pose_aggregate, cfg.pose_rotation_length_mm)
            per_pose = -np.where(np.isfinite(e), np.minimum(e, POSE_UNOBSERVABLE_MM), POSE_UNOBSERVABLE_MM)
            fields["pose"] = pose = _BatchPose(-per_pose, g)
        values = per_pose_values(_Arrays(fields), cfg, self.feature_mask)
        return np.stack([pose.g if k == "pose" and pose is not None else
                         aggregate(values[k], cfg.aggregate, cfg.smoothmin_beta, self.units[k])
                         for k in cfg.measures], axis=-1)

    def features_constraints(self, centres: np.ndarray, radii: np.ndarray, g: np.ndarray,
                             X: np.ndarray | None = None) -> np.ndarray:
        """Constraint margins (..., M) from features and raw objectives g (..., K) of designs X (..., P) (for
        host-face outlines that move with the design; None: the outlines of the reference holes)."""
        mech = self.cset.stacked(centres, radii, X)
        thr = (np.asarray(g)[..., self._thr_idx] - self._thr) / self.scales[self._thr_idx]
        return np.concatenate([mech, thr], axis=-1)

    # ------------------------------------------------------------------------------------ batched
    def evaluate_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Raw objectives G (B, K) and constraint margins C (B, M) of designs X (B, P).

        Features come from one ``features_batch`` call, the measures from one batched pass
        (``batch_objectives``) and the 2-D constraints from one vectorised call."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        centres, axes, radii = self.model.features_batch(X)
        G = self.batch_objectives(centres, np.broadcast_to(axes, centres.shape), radii, depth_mm=self.hole_depths(X))
        self.n_evals += len(X)
        return G, self.features_constraints(centres, radii, G, X)

    def combined_from(self, G: np.ndarray) -> np.ndarray:
        """The scalar to maximise (...,) from raw objectives G (..., K) (``objectives.combine``); with every
        measure thresholded, the smallest normalised threshold slack."""
        cfg = self.objective_config
        if cfg.combine == "constraint" and not cfg.objective_measures:
            return ((np.asarray(G)[..., self._thr_idx] - self._thr) / self.scales[self._thr_idx]).min(axis=-1)
        return combine(self.normalised(G), cfg, self.names, self.normaliser.constant)

    # ------------------------------------------------------------------------------ scalar helpers
    def objectives(self, x: np.ndarray) -> dict[str, float]:
        """Raw aggregated objectives {g_FOV, ...} at design ``x``."""
        G, _ = self.evaluate_batch(np.asarray(x, dtype=float)[None])
        return dict(zip(self.names, map(float, G[0]), strict=True))

    def normalised_objectives(self, x: np.ndarray) -> dict[str, float]:
        return self.normaliser.normalise(self.objectives(x))

    def combined(self, x: np.ndarray) -> float:
        """The combined objective to maximise at ``x``."""
        G, _ = self.evaluate_batch(np.asarray(x, dtype=float)[None])
        return float(self.combined_from(G[0]))

    def objective(self, x: np.ndarray) -> float:
        """The scalar to minimise: −combined."""
        return -self.combined(x)

    def constraints(self, x: np.ndarray) -> np.ndarray:
        """Constraint margins (M,) ≥ 0 feasible at ``x``."""
        return self.evaluate_batch(np.asarray(x, dtype=float)[None])[1][0]

    def constraint_labels(self) -> list[tuple[str, list[str]]]:
        """(kind, hole names) of each entry of ``constraints``."""
        out = [(kind, holes) for kind, entries in self.cset.labels().items() for holes in entries]
        return out + [(f"threshold:{self.names[i]}", []) for i in self._thr_idx]

    def constraint_kinds(self) -> list[str]:
        return [k for k, _ in self.constraint_labels()]
