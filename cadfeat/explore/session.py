"""One explorer session: a study loaded once, then every slider move scored by the study's own code.

``ExploreSession(study)`` sets the study up (``cadfeat.study.setup_cache.cached_setup``: CAD builds, the design map
∂F/∂P, the objective normaliser and the occlusion mesh — the slow part, done once — or all of it read from the
set-up cache when the same inputs were set up before, by ``cadfeat explore``, ``run`` or ``evaluate``).
``explore.loader.SessionLoader`` does that in a background thread, so that the server answers at once.
``evaluate(values, pose)`` is then
a feature-level
computation, no CAD: the feature model gives the holes at the design (``setup.model.features``, exact for
holes placed linearly by the parameters), ``cadfeat.study.run.measure_holes`` gives the (L, N) measures along
the trajectory with the exact occlusion ray test against the part mesh (what ``cadfeat evaluate`` uses), and
``cadfeat.design.objectives.objective_values`` aggregates them as ``evaluate`` and the optimiser do. Rays of
holes that did not move since an earlier call are answered from a cache (``raycache.CachedRayMesh``: the
same numbers, bit for bit). CAD rebuilds happen only on request (``export_step``, ``export_glb``).

The design the user chose can be written as a new study that starts there (``save_start``: a copy of the
study with ``[design.parameters] NAME.start``, next to the study, under a new name), or rebuilt and exported
as STEP / GLB into a new folder. Nothing existing is overwritten.
"""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
import tempfile
import threading
import time
import tomllib
from collections.abc import Mapping
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.cad.export import export_step
from cadfeat.cad.features import extract_holes
from cadfeat.cad.gltf import export_glb
from cadfeat.design.hole_form import design_depths
from cadfeat.errors import CadfeatError
from cadfeat.explore.status import SetupStatus
from cadfeat.study.pose_accuracy import with_pose

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.results import JsonDict
    from cadfeat.study.schema import StudyConfig

__all__ = ["ExploreSession", "new_path"]


def _plain(a: Any) -> Any:
    """JSON-ready nested lists; NaN / ±inf become None."""
    arr = np.asarray(a)
    if arr.dtype == bool:
        return arr.tolist()
    arr = arr.astype(float)
    out = np.where(np.isfinite(arr), arr, np.nan).tolist()

    def clean(v: Any) -> Any:
        if isinstance(v, list):
            return [clean(x) for x in v]
        return None if v is None or (isinstance(v, float) and math.isnan(v)) else v

    return clean(out)


def new_path(folder: Path, stem: str, suffix: str) -> Path:
    """``folder/stem-<k>suffix`` with the smallest k ≥ 1 that does not exist yet (never an existing file)."""
    k = 1
    while (folder / f"{stem}-{k}{suffix}").exists():
        k += 1
    return folder / f"{stem}-{k}{suffix}"


class ExploreSession:
    """A loaded study for the explorer (see the module docstring). Thread-safe: one evaluation at a time.

    ``cache``: read the set-up from the set-up cache / keep it there (None: on unless ``CADFEAT_CACHE=off``);
    ``status``: told each phase of the set-up (``SessionLoader``); ``config``: the study, loaded already."""

    def __init__(self, study: str | Path, results: str | Path | None = None, *, cache: bool | None = None,
                 status: SetupStatus | None = None, config: StudyConfig | None = None) -> None:
        # lazy: import cycle (cadfeat.explore.raycache imports cadfeat.explore.session)
        from cadfeat.explore.raycache import CachedRayMesh
        from cadfeat.study.schema import load_study
        from cadfeat.study.setup_cache import cached_setup, open_cache, save

        self.status = status if status is not None else SetupStatus()
        t0 = self.status.t0 if status is not None else time.perf_counter()
        self.study_path = Path(study).resolve()
        self.config = config if config is not None else load_study(self.study_path)
        self.timeout_s = self.config.study.build_timeout_s
        store = open_cache(cache)
        self.setup = cached_setup(self.config, time_limit_s=self.timeout_s, cache=store,  # (rebuilds keep the limit)
                                  on_phase=self.status.set_phase)
        s = self.setup
        entry = s.cache_entry
        self.status.cache = "off" if entry is None else "hit" if entry.hit else "miss"
        self.status.saved_s = entry.setup_s if entry is not None and entry.hit else None
        self.variables = list(s.space.variables)
        self.names = [v.name for v in self.variables]
        self.x0 = np.asarray(s.space.x0, float)
        mesh = s.problem.occlusion_mesh
        self.occlusion = None if mesh is None else CachedRayMesh(mesh)
        self.lock = threading.Lock()
        self.optimum = self._optimum(results)
        if s.problem.normaliser_built is None:
            self.status.set_phase("objective scales (the payoff table, on the feature map)")
            s.problem.normaliser  # noqa: B018 - built now (the first evaluation needs it)
        save(s)  # a fresh set-up: kept for the next start (with its normaliser and display mesh)
        self.status.set_phase("warm-up: the compiled measure kernels, the current design's occlusion rays")
        self.evaluate()  # warm-up: compiled measure kernels, the rays of the current design
        self.setup_s = time.perf_counter() - t0

    # ----------------------------------------------------------------------------------- static scene
    def _optimum(self, results: str | Path | None) -> dict[str, float] | None:
        """The optimised design of ``results.json`` (``--results``; default ``exports/<study name>/``)."""
        from cadfeat.study.run import default_out_dir  # lazy: would import scipy.optimize at module load

        path = Path(results) if results is not None else default_out_dir(self.config) / "results.json"
        if not path.is_file():
            if results is not None:
                raise CadfeatError(f"{path}: --results: no such file; allowed: a results.json written by cadfeat run")
            return None
        try:
            data = json.loads(path.read_text())
            after = {v["name"]: float(v["after"]) for v in data.get("variables", [])}
        except (ValueError, KeyError, TypeError) as exc:
            raise CadfeatError(f"{path}: not a cadfeat results.json ({exc}); allowed: a file written by cadfeat run"
                               ) from None
        return {n: after[n] for n in self.names if n in after} if after else None

    def scene(self) -> JsonDict:
        """What the page draws once: variables with bounds, the part mesh, the camera path and intrinsics,
        the hole names, the trajectory times, the current and (if any) the optimum design."""
        from cadfeat.poses import invert_T  # lazy: would import scipy.spatial at module load
        from cadfeat.report.view3d import mesh_arrays
        from cadfeat.study.setup_cache import product

        s = self.setup
        verts, tris = product(s, "display_mesh", lambda: mesh_arrays(s.shape0))  # (kept in the set-up cache)
        T_part_cam = invert_T(s.T_task_part) @ np.asarray(s.trajectory.T_task_cam, float)
        cam = s.camera
        return {
            "study": self.config.study.name, "file": str(self.study_path), "part": self.config.study.part,
            "variables": [{"name": v.name, "lower": float(v.lower), "upper": float(v.upper), "unit": v.unit,
                           "kind": v.kind, "value": float(x)} for v, x in zip(self.variables, self.x0, strict=True)],
            "holes": s.hole_names, "fixed": np.asarray(s.fixed_mask, bool).tolist(),
            "objectives": list(s.problem.names), "combine": self.config.objective.combine,
            "aggregate": self.config.objective.aggregate, "min_axis_px": self.config.objective.min_axis_px,
            "times_s": _plain(s.trajectory.times_s),
            "camera": {k: float(getattr(cam, k)) for k in ("fx", "fy", "cx", "cy", "width", "height")},
            "T_part_cam": _plain(T_part_cam),
            "mesh": {"vertices": _plain(verts.astype(np.float32)), "triangles": tris.astype(int).tolist()},
            "current": dict(zip(self.names, map(float, self.x0), strict=True)),
            "optimum": self.optimum, "setup_s": self.setup_s, "cache": self.status.cache,
        }

    # ------------------------------------------------------------------------------------ evaluation
    def design(self, values: Mapping[str, Any] | None) -> np.ndarray:
        """The design vector x of ``values`` (name → value; missing names: the current design), checked."""
        x = self.x0.copy()
        for name, value in dict(values or {}).items():
            if name not in self.names:
                raise CadfeatError(f"explore: unknown design variable {name!r}; allowed: {', '.join(self.names)}")
            v = self.variables[self.names.index(name)]
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise CadfeatError(f"explore: {name} = {value!r} is not a finite number")
            if not v.lower - 1e-9 <= value <= v.upper + 1e-9:
                raise CadfeatError(f"explore: {name} = {value:g} is outside [{v.lower:g}, {v.upper:g}]")
            x[self.names.index(name)] = float(value)
        return x

    def evaluate(self, values: Mapping[str, Any] | None = None, pose: int = 0) -> JsonDict:
        """Every number the page shows at design ``values`` (see the module docstring), with the synthetic
        camera view's predicted ellipses at trajectory sample ``pose``."""
        from cadfeat.design.objectives import objective_values  # lazy: would import pydantic at module load
        from cadfeat.study.run import measure_holes

        x = self.design(values)
        s = self.setup
        L = len(s.trajectory.times_s)
        if isinstance(pose, bool) or not isinstance(pose, int) or not 0 <= pose < L:
            raise CadfeatError(f"explore: pose {pose!r}; allowed: 0..{L - 1}")
        t0 = time.perf_counter()
        with self.lock:
            c, a, r = s.model.features(x)
            depths = design_depths(s.model, x)  # the design's hole depths (design.hole_form), else the holes' own
            depths = [h.depth_mm for h in s.model.holes] if depths is None else depths[0]
            holes = [SimpleNamespace(centre=c[j], axis=a[j], radius_mm=float(r[j]), through=h.through,
                                     depth_mm=float(depths[j])) for j, h in enumerate(s.model.holes)]
            m = measure_holes(s, holes, mesh=self.occlusion)
            if "pose" in self.config.objective.measures:  # g_POSE: the pose information of these holes

                m = with_pose(s, holes, s.trajectory, m, mesh=self.occlusion)
            objectives = objective_values(m, self.config.objective, s.problem.units, s.problem.feature_mask)
            G = np.array([objectives[n] for n in s.problem.names])
            combined = None if self.config.objective.combine == "pareto" else float(s.problem.combined_from(G))
            normalised = s.problem.normalised(G)
        elapsed = time.perf_counter() - t0
        return {
            "values": dict(zip(self.names, map(float, x), strict=True)),
            "objectives": objectives, "combined": combined,
            "normalised": dict(zip(s.problem.names, map(float, normalised), strict=True)),
            "holes": [{"name": n, "centre": _plain(c[j]), "axis": _plain(a[j]), "radius": float(r[j])}
                      for j, n in enumerate(s.hole_names)],
            "per_pose": {"fov": _plain(m.fov), "fov_px": _plain(m.fov_px), "focus": _plain(m.focus),
                         "resolution_px": _plain(m.resolution_px), "visible": _plain(m.visible),
                         "resolvability": _plain(m.resolvability), "condition": _plain(m.condition)},
            "pose": {"index": pose, "centre_px": _plain(m.centre_px[pose]), "axes_px": _plain(m.axes_px[pose]),
                     "angle_rad": _plain(m.angle_rad[pose]), "visible": _plain(m.visible[pose])},
            "elapsed_s": elapsed,
        }

    def sweep(self, values: Mapping[str, Any] | None, name: str, n: int = 41) -> JsonDict:
        """The objectives along design variable ``name`` over its bounds, the others at ``values`` (as the thesis
        plots them against the design variable, Figs. 5.10-5.11): ``n`` designs scored in one batch by the
        optimiser's own function (``Problem.evaluate_batch``: the depth-map occlusion test), normalised, with
        the combined score and whether the kept requirements hold there."""
        x = self.design(values)
        if name not in self.names:
            raise CadfeatError(f"explore: unknown design variable {name!r}; allowed: {', '.join(self.names)}")
        if isinstance(n, bool) or not isinstance(n, int) or not 2 <= n <= 201:
            raise CadfeatError(f"explore: sweep of {n!r} points; allowed: 2..201")
        i = self.names.index(name)
        v = self.variables[i]
        X = np.repeat(x[None], n, axis=0)
        X[:, i] = np.linspace(v.lower, v.upper, n)
        problem = self.setup.problem
        with self.lock:
            G, C = problem.evaluate_batch(X)
            normalised = problem.normalised(G)
            combined = None if self.config.objective.combine == "pareto" else problem.combined_from(G)
        feasible = np.all(np.asarray(C) >= 0, axis=1) if np.size(C) else np.ones(n, bool)
        return {"name": name, "x": _plain(X[:, i]), "at": float(x[i]),
                "normalised": {k: _plain(normalised[:, j]) for j, k in enumerate(problem.names)},
                "combined": None if combined is None else _plain(combined), "feasible": _plain(feasible)}

    # ------------------------------------------------------------------------------------ outputs
    def save_start(self, values: Mapping[str, Any] | None) -> Path:
        """Write the study with ``[design.parameters] NAME.start`` = the chosen design, next to the study file
        as ``<stem>-start-<k>.toml`` (a new file; the study itself is only read). Script studies only."""
        import tomli_w

        if self.config.study.part_kind != "script":
            raise CadfeatError(f"{self.study_path}: a STEP study has no parameters to start from; export the STEP "
                               "instead")
        x = self.design(values)
        data = tomllib.loads(self.study_path.read_text(encoding="utf-8"))
        design = data.setdefault("design", {})
        raw = design.get("parameters", {})
        table = {n: {} for n in raw} if isinstance(raw, list) else {k: dict(v) for k, v in raw.items()}
        for name, value in zip(self.names, x, strict=True):
            table.setdefault(name, {})["start"] = float(value)
        design["parameters"] = table
        target = new_path(self.study_path.parent, f"{self.study_path.stem}-start", ".toml")
        header = (f"# Written by `cadfeat explore` from {self.study_path.name}: the same study, starting at the design "
                  "chosen in the explorer\n# ([design.parameters] NAME.start). `cadfeat evaluate` scores that design; "
                  "`cadfeat run` starts the optimiser there.\n\n")
        text = header + tomli_w.dumps(data)
        tmp = target.with_name(f".{target.name}.part")
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(target)
        return target

    def rebuild(self, values: Mapping[str, Any] | None) -> Any:
        """The real CAD model at the chosen design (time-limited build): a ``cadquery.Solid``."""
        return self.setup.rebuild_shape(self.design(values))

    def rebuilt_mesh(self, values: Mapping[str, Any] | None) -> JsonDict:
        """The CAD model rebuilt at the chosen design, triangulated for the page (vertices mm, triangles)."""
        from cadfeat.report.view3d import mesh_arrays  # lazy: would import pydantic at module load

        verts, tris = mesh_arrays(self.rebuild(values))
        return {"vertices": _plain(verts.astype(np.float32)), "triangles": tris.astype(int).tolist()}

    def _named(self, holes: list[Any], x: np.ndarray) -> list[Any]:
        """Rebuilt ``holes`` named as the explorer names them: each takes the name of the predicted hole
        (feature model at ``x``) it matches one to one by centre distance and radius (Hungarian)."""
        from scipy.optimize import linear_sum_assignment

        if not holes:
            return holes
        c, _, r = self.setup.model.features(x)
        got = np.array([h.centre for h in holes], float)
        radii = np.array([h.radius_mm for h in holes], float)
        cost = np.linalg.norm(got[:, None] - c[None], axis=-1) + np.abs(radii[:, None] - r[None])
        rows, cols = linear_sum_assignment(cost)
        names = {int(i): self.setup.hole_names[int(k)] for i, k in zip(rows, cols, strict=True)}
        extra = iter(f"X{k + 1}" for k in range(len(holes)))
        return [dataclasses.replace(h, name=names.get(i) or next(extra)) for i, h in enumerate(holes)]

    def export(self, values: Mapping[str, Any] | None, folder: str | Path | None = None) -> dict[str, str]:
        """Rebuild the chosen design in CAD and write ``design.step`` and ``design.glb`` (hole names as glTF
        node names) into a NEW folder ``<folder>/explore-<k>`` (default folder: beside the study)."""
        shape = self.rebuild(values)
        base = Path(folder) if folder is not None else self.study_path.parent
        target = new_path(base, f"{self.config.study.name}-explore", "")
        stage = Path(tempfile.mkdtemp(prefix=".explore-", dir=base))
        try:
            export_step(shape, stage / "design.step")
            view = self.setup.view_direction  # the study's view: through holes enter as in its set-up
            holes = extract_holes(shape, prefer_direction=view)
            export_glb(shape, self._named(holes, self.design(values)), stage / "design.glb")
            stage.replace(target)
        except BaseException:
            shutil.rmtree(stage, ignore_errors=True)
            raise
        return {"folder": str(target), "step": str(target / "design.step"), "glb": str(target / "design.glb")}

