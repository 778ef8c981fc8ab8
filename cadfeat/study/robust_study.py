"""The robust redesign in a study run (issue 18): optimise for the cell that will be built, compare, recommend.

Two steps, each attached to the pipeline (``cadfeat.study.pipeline.compute``) by one line:

- ``robust_phase(config, opt, progress, history)`` (optimise phase, after the nominal optimisation): with
  ``[robustness] robust = true`` (the default), local solves of the robust problem (``cadfeat.design.robust``)
  from the nominal optimum, the best end-points of the nominal multi-start and the initial design, on
  ``draws`` fixed draws (seed: the study's); the robust optimum replaces the optimiser's result (it is the
  design the shop rounding and the CAD rebuild deliver) unless it fails the rule below on held-out draws and the
  nominal optimum passes it. Returns a ``RobustRun`` (None when robust is off, the run was interrupted, the
  combination is Pareto or the feature map is not linear — then the note says so).
- ``robust_designs(setup, run, holes0, holes1)`` (analyse phase): the typed ``RobustDesigns`` of results.json
  ``robustness`` (``to_json``): the original, the recommended and (when the robust optimum is recommended) the
  nominal optimum, each per source of uncertainty (cell = all cell sources together, camera, placement, path,
  pixel_noise, manufacturing) with nominal/mean/p05/p10/min of every objective and of the combined value, on
  ``samples`` draws of a held-out seed (study seed + 1); the in-sample vs out-of-sample robust statistic of each
  design; which source the recommended design is most sensitive to (one-at-a-time 5th-percentile drops).

The rule (docs/design.md "Uncertainty"): a design whose combined objective's 5th percentile is below the original's,
under the whole cell, the camera mounting error or the shop's tolerances (``design.robust.BLOCKS``, the sources
the robust optimiser holds to the original's in sample), is never recommended; the original is then
(``recommended = "original"``). The other sources alone are diagnostics ("where the robustness comes from").
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, TypedDict

import numpy as np

from cadfeat.cad.features import holes_to_arrays
from cadfeat.design.hole_form import hole_depths
from cadfeat.design.robust import BLOCKS, RobustObjective, RobustProblem, robust_optimise, statistic
from cadfeat.design.robustness import cell_objectives, shop_objectives
from cadfeat.design.uncertainty import CELL_KINDS, KINDS, Draws, Uncertainty, draws

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.cad.features import Hole
    from cadfeat.design.design_space import DesignSpace
    from cadfeat.design.optimize import OptimResult
    from cadfeat.results import HistoryPointData, JsonDict, ResultsData
    from cadfeat.study.progress import StudyProgress
    from cadfeat.study.schema import StudyConfig
    from cadfeat.study.setup import StudySetup

__all__ = ["HELD_OUT_SEED_OFFSET", "SOURCES", "DesignStats", "RobustDesigns", "RobustRun", "attach_robust",
           "check_robust", "design_statistics",
           "robust_designs", "robust_phase", "source_objectives", "statistics_of"]

SOURCES = ("cell", *KINDS)
"""The perturbations of results.json ``robustness.designs``: every cell source together, then one at a time."""
HELD_OUT_SEED_OFFSET = 1
"""The held-out draws' seed is the study's plus this (the robust objective's draws use the study's seed)."""
TOL = 1e-9
"""Relative slack of the "never below the original" rule (rounding)."""
SOURCE_WORDS = {"camera": "the camera mounting error", "placement": "the part's placement in the cell",
                "path": "the path variation (offset, time scaling)", "pixel_noise": "the pixel noise",
                "manufacturing": "the shop's hole tolerances", "cell": "the cell (all its sources together)"}


def check_robust(config: StudyConfig) -> None:
    """Refuse, before any work, a chance constraint on a measure the study does not optimise (one line)."""
    from cadfeat.study.schema import StudyError  # lazy: would import scipy.spatial at module load

    spec = config.robustness
    if spec.statistic == "chance" and spec.chance_measure not in config.objective.measures:
        raise StudyError(f"{config.label}: robustness.chance_measure: {spec.chance_measure!r} is not allowed; "
                         f"allowed: one of objective.measures ({', '.join(config.objective.measures)})")


@dataclass
class RobustRun:
    """The optimise phase's robust step: the nominal and robust optimisers' results, the problem and draws the
    robust one saw, which design goes to the shop (``delivered``: "robust" or "nominal") and why."""

    nominal: OptimResult
    robust: OptimResult
    problem: RobustProblem
    delivered: str
    note: str = ""


class Optimum(Protocol):
    """What the robust step reads and updates of the optimise phase's outcome (``pipeline._Optimum``): the best
    set-up, its optimiser result (replaced by the robust one when that is delivered), the history, interrupted?"""

    setup: StudySetup
    res: OptimResult
    history: list[HistoryPointData]
    interrupted: bool


class Spread(TypedDict):
    """One objective's (or the combined value's) statistics over draws (``_block``)."""

    nominal: float
    mean: float
    p05: float
    p10: float
    min: float


def _uncertainty(config: StudyConfig) -> tuple[Uncertainty, RobustObjective]:
    spec = config.robustness
    return Uncertainty.from_settings(spec, config.cell), RobustObjective.from_settings(spec)


def _starts(opt: Optimum, space: DesignSpace, most: int = 2) -> list[np.ndarray]:
    """The nominal optimum, the ``most`` best other end-points of the nominal multi-start, the initial design
    (distinct, in that order)."""
    out = [np.asarray(opt.res.x_best, float)]
    ends = sorted(((s["x_end"], s["combined"] or 0.0) for s in opt.res.starts
                   if "x_end" in s and s.get("max_violation", 0.0) <= 1e-6), key=lambda s: -float(s[1]))
    for x_end, _ in ends:
        if len(out) > most:
            break
        out.append(np.asarray(x_end, float))
    out.append(np.asarray(space.x0, float))
    span = np.maximum(np.asarray(space.upper, float) - np.asarray(space.lower, float), 1e-12)
    distinct: list[np.ndarray] = []
    for x in out:  # distinct: more than 0.1 % of a variable's range apart
        if not any(np.max(np.abs(x - y) / span) < 1e-3 for y in distinct):
            distinct.append(x)
    return distinct


def robust_phase(config: StudyConfig, opt: Optimum, progress: StudyProgress,
                 history: Callable[[OptimResult, str], list[HistoryPointData]]) -> RobustRun | None:
    """The robust optimum of the best set-up (module docstring); ``opt.res`` becomes the delivered design's
    optimiser result and ``opt.history`` gains the robust solves (phase "robust") as ``history(result, label)``
    formats them (the pipeline's ``_history``)."""
    spec = config.robustness
    setup = opt.setup
    interrupts = getattr(progress, "interrupts", None)
    if interrupts is not None and interrupts.requested:  # (Ctrl-C: the nominal optimum is delivered)
        opt.interrupted = True
    if not spec.robust or opt.interrupted:
        return None
    if config.objective.combine == "pareto" or not setup.linear:
        progress.log("robust optimisation skipped: it needs one combined objective (not pareto) and a linear "
                     "feature map (not the CAD trust-region loop); the nominal optimum is delivered")
        return None
    unc, objective = _uncertainty(config)
    problem = setup.problem
    D = draws(unc, spec.draws, len(problem.model.holes), config.study.seed, spec.sampling)
    rp = RobustProblem(problem, objective, D, floor_x=setup.space.x0)
    nominal = opt.res
    try:
        with interrupts.keeping() if interrupts is not None else contextlib.nullcontext():
            res = robust_optimise(rp, config.optimizer, _starts(opt, setup.space), progress=progress.iteration)
    except KeyboardInterrupt:  # before the robust solve evaluated anything: the nominal optimum is delivered
        opt.interrupted = True
        return None
    opt.history += history(res, "robust")
    held = draws(unc, spec.samples or 64, len(problem.model.holes), config.study.seed + HELD_OUT_SEED_OFFSET,
                 spec.sampling)
    delivered, note = _choose(setup, rp, nominal, res, held)
    if delivered == "robust":
        opt.res = res
    opt.interrupted = opt.interrupted or bool(res.interrupted)
    return RobustRun(nominal, res, rp, delivered, note)


def _choose(setup: StudySetup, rp: RobustProblem, nominal: OptimResult, robust: OptimResult, held: Draws
            ) -> tuple[str, str]:
    """"robust" unless, on held-out draws, the robust optimum's 5th percentile falls below the original's under a
    source while the nominal optimum's does not, or the nominal optimum (its 5th percentiles not below the
    original's) has the higher robust statistic — the robust solve did not improve on it (then "nominal").

    The three designs (original, robust, nominal optimum; each with its hole depths) are evaluated ONCE on the
    held-out draws (``source_objectives``): the floors' statistics and the robust statistic come from the same
    arrays."""
    X = np.stack([np.asarray(x, float) for x in (setup.space.x0, robust.x_best, nominal.x_best)])
    c, a, r = setup.model.features_batch(X)
    G0, G = source_objectives(rp, (c, a, r), held, BLOCKS, rp.inner.hole_depths(X))
    stats = statistics_of(rp, G0, G)
    below = [_below(stats[k], stats[0]) for k in (1, 2)]
    if below[0] and not below[1]:
        return "nominal", (f"the robust optimum's 5th percentile is below the original's under {', '.join(below[0])}; "
                           "the nominal optimum's is not: the nominal optimum is delivered")
    same = np.allclose(robust.x_best, nominal.x_best, rtol=0.0, atol=1e-9)  # the robust solve kept its start
    if not below[1] and not same and rp.objective.statistic != "chance":
        other = RobustProblem(rp.inner, rp.objective, held, rp.changed)
        value, _ = other.value_and_margins({"nominal": G0, **G})
        v_robust, v_nominal = float(value[1]), float(value[2])
        if v_nominal > v_robust + 1e-9 * max(1.0, abs(v_robust)):
            return "nominal", (f"the nominal optimum's {rp.objective.label} on held-out draws ({v_nominal:.4g}) is "
                               f"above the robust optimum's ({v_robust:.4g}): the robust solve did not improve on "
                               "it, the nominal optimum is delivered")
    return "robust", ""


def _below(stats: DesignStats, original: DesignStats) -> list[str]:
    """The sources the rule covers (``design.robust.BLOCKS``: the whole cell, the camera mount, the shop) under
    which a design's combined 5th percentile is below the original's."""
    out: list[str] = []
    for src in BLOCKS:
        a, b = stats.blocks[src].get("combined"), original.blocks[src].get("combined")
        if a and b and a["p05"] < b["p05"] - TOL * max(1.0, abs(b["p05"])):
            out.append(src)
    return out


def _block(G: np.ndarray, G0: np.ndarray, names: list[str], combined: np.ndarray | None,
           c0: float | None) -> dict[str, Spread]:
    """nominal/mean/p05/p10/min of each objective (S, K) and of the combined values (S,)."""
    def st(v: np.ndarray, nom: float) -> Spread:
        return {"nominal": float(nom), "mean": float(v.mean()), "p05": float(np.percentile(v, 5)),
                "p10": float(np.percentile(v, 10)), "min": float(v.min())}
    out = {n: st(G[:, k], G0[k]) for k, n in enumerate(names)}
    if combined is not None and c0 is not None:
        out["combined"] = st(combined, c0)
    return out


Features = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass
class DesignStats:
    """One design's statistics per source of uncertainty (``statistics_of``): per source, ``_block`` of its draws
    (``blocks``: per objective and "combined" a ``Spread``); with ``values``, the combined value per draw and source
    (``values``) and each objective's per draw under the whole cell (``objective_values``), for the report."""

    blocks: dict[str, dict[str, Spread]] = field(default_factory=dict[str, dict[str, Spread]])
    values: dict[str, list[float]] = field(default_factory=dict[str, list[float]])
    objective_values: dict[str, list[float]] = field(default_factory=dict[str, list[float]])


Depths = np.ndarray | Sequence[np.ndarray | None] | None
"""Hole depths (mm) of B designs: (B, N), a (N,) array or None per design, or None (the reference holes')."""


def _design_depths(rp: RobustProblem, depths: Depths, B: int) -> np.ndarray:
    """(B, N) hole depths (mm) of B designs: ``depths`` (B, N), or a list of (N,) / None per design (None: the
    reference holes' depths, as ``design.pose_terms.hole_attributes`` takes them)."""
    ref = hole_depths(rp.inner.model.holes)
    if depths is None:
        return np.tile(ref, (B, 1))
    return np.stack([ref if d is None else np.asarray(d, float).reshape(-1) for d in depths])


def source_objectives(rp: RobustProblem, features: Features, D: Draws, sources: tuple[str, ...] = SOURCES,
                      depths: Depths = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Raw objectives of B designs' features (B, N, 3), (B, N, 3), (B, N) with hole depths ``depths`` (B, N) mm
    (or a list of (N,)/None per design; None: the reference holes'): nominal (B, K) and, per source of
    ``sources``, (B, S, K) on the draws ``D`` with only that source (the cell sources together for "cell"); one
    batch of the B designs per source."""
    p = rp.inner
    c, a, r = (np.asarray(v, float) for v in features)
    a = np.broadcast_to(a, c.shape)
    depth = _design_depths(rp, depths, len(r))
    first, back = _distinct_designs(c, a, r, depth)  # the same design twice (e.g. robust = nominal) costs once
    c, a, r, depth = c[first], a[first], r[first], depth[first]
    G0 = p.batch_objectives(c, a, r, depth_mm=depth)
    out: dict[str, np.ndarray] = {}
    for src in sources:
        d = D.only(src)
        if src == "pixel_noise" and "pose" not in p.objective_config.measures:  # only g_POSE's σ model sees it
            out[src] = np.repeat(G0[:, None], d.size, axis=1)
        elif src == "manufacturing":
            out[src] = shop_objectives(p, c, a, r, rp.changed, d, depth)
        else:
            out[src] = cell_objectives(p, c, a, r, d, depth)
    return G0[back], {src: v[back] for src, v in out.items()}


def _distinct_designs(*arrays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, back): the indices of the first of each distinct design (rows of ``arrays`` bit-equal in all of
    them) and, per design, the index of its distinct design in ``first`` (``x[first][back]`` gives ``x``)."""
    keys = [b"".join(np.ascontiguousarray(x[i]).tobytes() for x in arrays) for i in range(len(arrays[0]))]
    seen: dict[bytes, int] = {}
    back = np.array([seen.setdefault(k, len(seen)) for k in keys], dtype=int)
    first = np.array([keys.index(k) for k in seen], dtype=int)
    return first, back


def statistics_of(rp: RobustProblem, G0: np.ndarray, G: dict[str, np.ndarray],
                  values: bool = False) -> list[DesignStats]:
    """Per design, per source: ``_block`` of ``source_objectives``' arrays (``design_statistics``)."""
    p = rp.inner
    pareto = p.objective_config.combine == "pareto"
    c0 = None if pareto else np.asarray(p.combined_from(G0), float)
    out = [DesignStats() for _ in range(len(G0))]
    for src, Gs in G.items():
        comb = None if pareto else np.asarray(p.combined_from(Gs), float)
        for b in range(len(G0)):
            out[b].blocks[src] = _block(Gs[b], G0[b], list(p.names), None if comb is None else comb[b],
                                        None if c0 is None else float(c0[b]))
            if values and comb is not None:
                out[b].values[src] = comb[b].tolist()
                if src == "cell":
                    out[b].objective_values.update({n: Gs[b, :, k].tolist() for k, n in enumerate(p.names)})
    return out


def design_statistics(rp: RobustProblem, features: list[Features], D: Draws, values: bool = False,
                      sources: tuple[str, ...] = SOURCES, depths: Depths = None) -> list[DesignStats]:
    """Per design (features (N, 3), (N, 3), (N,) each; ``depths``: its hole depths (N,) mm or None for the
    reference holes'), per source of ``sources``: ``_block`` of the draws ``D`` with only that source (the cell
    sources together for "cell"); the designs evaluated as one batch per source (``source_objectives``).
    ``values``: also each source's combined value per draw (``DesignStats.values``, for the report's plots)."""
    c, a, r = (np.stack([np.asarray(f[i], float) for f in features]) for i in range(3))
    G0, G = source_objectives(rp, (c, a, r), D, sources, depths)
    return statistics_of(rp, G0, G, values)


def _robust_value(rp: RobustProblem, features: list[Features], depths: Depths = None) -> list[float]:
    """The robust statistic of each design (hole depths ``depths``, as ``design_statistics``) on ``rp``'s draws,
    as the optimiser computes it (for "chance": the 10th percentile of the combined value, the default
    statistic)."""
    if rp.objective.statistic == "chance":
        rp = RobustProblem(rp.inner, RobustObjective(), rp.draws, rp.changed)
    c, a, r = (np.stack([np.asarray(f[i], float) for f in features]) for i in range(3))
    depth = _design_depths(rp, depths, len(r))
    first, back = _distinct_designs(c, a, r, depth)
    value, _ = rp.value_and_margins(rp.block_objectives(c[first], a[first], r[first], depth[first]))
    return [float(x) for x in np.asarray(value)[back]]


@dataclass
class RobustDesigns:
    """results.json ``robustness`` additions (issue 18): see the module docstring; ``to_json`` gives the keys
    ``objective``, ``uncertainty``, ``designs``, ``recommended``, ``delivered``, ``reason``, ``out_of_sample``,
    ``sensitivity``, ``flagged`` and ``distributions`` (combined value per held-out draw and source, per design)."""

    objective: JsonDict
    uncertainty: JsonDict
    designs: dict[str, dict[str, dict[str, Spread]]]
    recommended: str
    delivered: str
    reason: str
    out_of_sample: JsonDict
    sensitivity: JsonDict
    flagged: list[str] = field(default_factory=list[str])
    distributions: dict[str, dict[str, dict[str, list[float]]]] = field(
        default_factory=dict[str, dict[str, dict[str, list[float]]]])

    def to_json(self) -> JsonDict:
        return dataclasses.asdict(self)


def robust_designs(setup: StudySetup, run: RobustRun | None, holes0: Sequence[Hole], holes1: Sequence[Hole]
                   ) -> RobustDesigns | None:
    """The comparison of the original, the delivered and the other optimum (module docstring); None when the
    robust step did not run or the hole counts differ."""
    if run is None or len(holes0) != len(holes1) or len(holes1) != len(run.problem.changed):
        return None
    config = setup.config
    spec = config.robustness
    rp = run.problem
    other = "nominal" if run.delivered == "robust" else "robust"
    x_other = (run.nominal if other == "nominal" else run.robust).x_best
    same = bool(np.allclose(run.robust.x_best, run.nominal.x_best, rtol=0.0, atol=1e-9))
    delivered_feats = holes_to_arrays(list(holes1))
    feats = {"original": holes_to_arrays(list(holes0)), run.delivered: delivered_feats,
             # the same optimum: the same (shop-rounded, rebuilt) design; else the other optimum as solved
             other: delivered_feats if same else setup.model.features(np.asarray(x_other, float))}
    order = ["original", run.delivered, other]
    other_depths = setup.problem.hole_depths(np.asarray(x_other, float)[None])
    depths = {"original": hole_depths(list(holes0)), run.delivered: hole_depths(list(holes1)),
              other: hole_depths(list(holes1)) if same else None if other_depths is None else other_depths[0]}
    samples = spec.samples or 64
    seed_out = config.study.seed + HELD_OUT_SEED_OFFSET
    held = draws(Uncertainty.from_settings(spec, config.cell), samples, len(rp.changed), seed_out, spec.sampling)
    stats = dict(zip(order, design_statistics(rp, [feats[k] for k in order], held, values=True,
                                              depths=[depths[k] for k in order]), strict=True))
    dists = {k: {"combined": v.values, "objectives_cell": v.objective_values} for k, v in stats.items()}
    below = {k: _below(stats[k], stats["original"]) for k in order[1:]}
    if not below[run.delivered]:
        recommended, reason = run.delivered, (
            f"the {run.delivered} optimum's 5th percentile is at least the original's under every source")
    elif not below[other]:
        recommended, reason = other, (
            f"the {run.delivered} optimum's 5th percentile is below the original's under "
            f"{', '.join(below[run.delivered])}; the {other} optimum's is not")
    else:
        recommended, reason = "original", (
            f"both optima's 5th percentile is below the original's (the {run.delivered} one under "
            f"{', '.join(below[run.delivered])}): keep the original")
    if same:
        reason = "the robust solve kept the nominal optimum (no design beats it on the draws); " + reason
    if run.note:
        reason = run.note + "; " + reason
    designs = {"original": stats["original"].blocks, "recommended": stats[recommended].blocks}
    for k in (run.delivered, other):
        if k != recommended:
            designs[k] = stats[k].blocks
    flagged = [k for k in order[1:] if below[k]]
    in_vals = _robust_value(rp, [feats[k] for k in order], [depths[k] for k in order])
    stat = rp.objective if rp.objective.statistic != "chance" else RobustObjective()
    out_vals = [float(min(statistic(np.asarray(dists[k]["combined"][b]), stat) for b in BLOCKS))
                for k in order]  # the held-out draws' combined values, already evaluated per source
    label = rp.objective.label if rp.objective.statistic != "chance" else "p10"
    oos: JsonDict = {"statistic": label, "draws_in_sample": rp.draws.size, "seed_in_sample": config.study.seed,
                     "draws_out_of_sample": samples, "seed_out_of_sample": seed_out,
                     "designs": {k: {"in_sample": i, "out_of_sample": o}
                                 for k, i, o in zip(order, in_vals, out_vals, strict=True)}}
    unc, objective = _uncertainty(config)
    return RobustDesigns(
        objective={"robust": bool(spec.robust), "statistic": objective.statistic, "label": objective.label,
                   "percentile": objective.percentile, "chance_measure": objective.chance_measure,
                   "chance_min": objective.chance_min, "chance_probability": objective.chance_probability,
                   "draws": rp.draws.size, "sampling": spec.sampling, "seed": config.study.seed},
        uncertainty=unc.to_dict(), designs=designs, recommended=recommended, delivered=run.delivered, reason=reason,
        out_of_sample=oos, sensitivity=sensitivity(stats[recommended].blocks), flagged=flagged, distributions=dists)


def attach_robust(results: ResultsData, designs: RobustDesigns | None) -> None:
    """results.json ``robustness`` gains the ``RobustDesigns`` keys (the block is created when the delivered
    design's own analysis is off)."""
    if designs is not None:
        results["robustness"] = {**(results.get("robustness") or {}), **designs.to_json()}


def sensitivity(stats: Mapping[str, Mapping[str, Spread]]) -> JsonDict:
    """Where a design's robustness comes from: per source, the combined value's one-at-a-time drop from nominal
    to the 5th percentile and its share of the sum of these drops; ``words``: the ranking in a sentence."""
    drops: dict[str, float] = {}
    for src in KINDS:
        comb = stats.get(src, {}).get("combined")
        if comb:
            drops[src] = max(0.0, comb["nominal"] - comb["p05"])
    total = sum(drops.values())
    shares = {k: (v / total if total > 0 else 0.0) for k, v in drops.items()}
    ranked = sorted(drops, key=lambda k: -drops[k])
    if not ranked or total <= 0:
        words = "the combined objective's 5th percentile does not drop under any single source"
    else:
        first = ranked[0]
        words = (f"most sensitive to {SOURCE_WORDS[first]} (its 5th percentile {drops[first]:.3g} below nominal, "
                 f"{100 * shares[first]:.0f} % of the one-at-a-time drops)")
        rest = [k for k in ranked[1:] if drops[k] > 0]
        if rest:
            words += "; then " + ", ".join(f"{SOURCE_WORDS[k]} ({100 * shares[k]:.0f} %)" for k in rest)
        cell = stats.get("cell", {}).get("combined")
        if cell:
            words += f"; all cell sources together: 5th percentile {cell['nominal'] - cell['p05']:.3g} below nominal"
    return {"drop_p05": drops, "share": shares, "order": ranked, "words": words,
            "cell_sources": list(CELL_KINDS)}
