"""Benchmark: added target holes (issue 31) on the flagship NEMA 17 mount.

Times, on the original mount and the candidate sites of ``studies/nema17_add_targets.toml`` (Ø5.5 blind on the
motor face and the base flange top, outside the motor): the candidate sites, the objective's set-up (every site's
rim occlusion by the exact ray test at every pose), and choosing k = 1..max_added holes by the lazy greedy —
against the plain greedy (every feasible site evaluated at every step) as the baseline; then the whole added-target
study (``cadfeat run``, phase by phase) with its closed-loop check: the original, the move-only optimum and the
delivered design (with the added holes) in the same paired runs. ``--quick``: the study without its closed-loop
check; ``--out DIR``: keep the study's output folder there (default: a temporary folder).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from benchutil import load as _load
from benchutil import save_section

STUDY = ROOT / "studies" / "nema17_add_targets.toml"


def _plain_greedy(evaluate, clash, k_max):  # type: ignore[no-untyped-def]
    """The baseline: every feasible site evaluated at every step (one batched call per step)."""
    import numpy as np

    chosen: list[int] = []
    values = [float(evaluate(np.zeros((1, 0), int))[0])]
    for _ in range(k_max):
        ok = np.flatnonzero(~clash[chosen].any(axis=0)) if chosen else np.arange(len(clash))
        g = evaluate(np.concatenate([np.broadcast_to(np.asarray(chosen, int), (len(ok), len(chosen))),
                                     ok[:, None]], axis=1))
        chosen.append(int(ok[int(np.argmax(g))]))
        values.append(float(g.max()))
    return chosen, values


def _choice_rows(config, setup):  # type: ignore[no-untyped-def]
    from cadfeat.design.added_targets import conflicts, lazy_greedy
    from cadfeat.study.added_targets import allowed_sites, pose_scene, target_objective
    from cadfeat.study.pose_accuracy import part_mesh

    spec = config.add_targets
    t = time.perf_counter()
    mesh = part_mesh(config, setup.shape0)
    allowed = allowed_sites(config, setup.shape0, setup.holes0)
    t_sites = time.perf_counter() - t
    t = time.perf_counter()
    obj = target_objective(config, pose_scene(config, setup), setup.holes0, mesh, allowed.sites)
    t_obj = time.perf_counter() - t
    clash = conflicts(allowed.sites, spec.rim_radius_mm, config.constraints.ligament_mm)
    rows = []
    for k in range(1, spec.max_added + 1):
        obj.evaluations = 0
        t = time.perf_counter()
        res = lazy_greedy(obj.of_sets, clash, k)
        t_lazy, n_lazy = time.perf_counter() - t, obj.evaluations
        obj.evaluations = 0
        t = time.perf_counter()
        order, values = _plain_greedy(obj.of_sets, clash, k)
        t_plain, n_plain = time.perf_counter() - t, obj.evaluations
        rows.append((k, t_lazy, n_lazy, t_plain, n_plain, -res.values[-1], -values[-1], res.order == order))
    return len(allowed.sites), t_sites, t_obj, rows


def _tracking_lines(r: dict) -> list[str]:  # type: ignore[type-arg]
    """The closed loop of the three designs (results.json ``tracking``: the delivered design against the original,
    and its ``comparisons``), median RMS translation / rotation error over the runs and the paired verdicts."""
    tr = r.get("tracking") or {}
    if not tr.get("verdicts"):
        return [f"Closed loop: {'; '.join(w for w in r.get('warnings', []) if 'closed-loop' in w) or 'off'}."]
    check, designs = tr.get("check") or {}, tr["designs"]

    def med(design: str, m: str, key: str) -> str:
        return f"{designs[design]['estimators'][m][key]['median']:.4f}"

    def verdicts(v: dict) -> str:  # type: ignore[type-arg]
        return "; ".join(f"{m.upper()} {x['verdict']} (p = {x['translation']['p_value']:.2g} translation, "
                         f"{x['rotation']['p_value']:.2g} rotation)" for m, x in v.items())

    st = tr["settings"]
    lines = [f"Closed loop ({check.get('mode')} check, {st['runs']} paired runs, {st['frames']} frames; paired "
             f"Wilcoxon signed-rank, α = {st['alpha']:g}, a change counts when significant and ≥ "
             f"{100 * st['min_change']:g} %), median RMS error over the runs, original → move-only optimum → "
             "delivered design:"]
    lines += [f"- {m.upper()}: translation {med('before', m, 'trans_mm_rms')} → "
              f"{med('move_only', m, 'trans_mm_rms')} → {med('after', m, 'trans_mm_rms')} mm, rotation "
              f"{med('before', m, 'rot_deg_rms')} → {med('move_only', m, 'rot_deg_rms')} → "
              f"{med('after', m, 'rot_deg_rms')}°" for m in tr["verdicts"]]
    lines += ["", f"Delivered design vs the original (the verdict's tracking rule): {verdicts(tr['verdicts'])}."]
    names = {"move_only_vs_original": "Move-only optimum vs the original",
             "added_vs_move_only": "Delivered design vs the move-only optimum"}
    lines += [f"{names.get(k, k)}: {verdicts(c['verdicts'])}." for k, c in (tr.get("comparisons") or {}).items()]
    verdict = r.get("verdict") or {}
    lines.append(f"Verdict: {verdict.get('decision')}.")
    return lines


def main(quick: bool = False, out: Path | None = None) -> str:
    from cadfeat.study.run import run_study
    from cadfeat.study.schema import load_study
    from cadfeat.study.setup import setup_study

    machine = _load("run_all", HERE / "run_all.py").machine_description()
    load0 = os.getloadavg()
    config = load_study(STUDY)
    setup = setup_study(config)
    n_sites, t_sites, t_obj, rows = _choice_rows(config, setup)
    lines = [
        "## Added target holes: choosing k holes, and the whole study (bench_add_targets)",
        "",
        f"Machine: {machine}. Flagship NEMA 17 mount as it is (original holes), {n_sites} candidate sites "
        f"({config.add_targets.pitch_mm:g} mm grid on the motor face and the base flange top), "
        f"{len(setup.trajectory.times_s)} poses; one run each.",
        "",
        f"Candidate sites (planar faces, 2-D requirements): {t_sites:.2f} s. Objective set-up (each site's rim "
        f"occlusion, exact ray test at every pose): {t_obj:.2f} s.",
        "",
        "| k | lazy greedy (s) | designs evaluated | plain greedy, baseline (s) | designs evaluated | ratio "
        "| predicted error lazy / plain (mm) | same choice |",
        "|---:|---:|---:|---:|---:|---:|---|---|",
    ]
    lines += [f"| {k} | {tl:.2f} | {nl} | {tp:.2f} | {np_} | {tl / tp:.2f} | {el:.5f} / {ep:.5f} | {same} |"
              for k, tl, nl, tp, np_, el, ep, same in rows]
    env = os.environ.copy()
    if quick:
        os.environ["CADFEAT_TRACKING_CHECK"] = "off"
    try:
        with tempfile.TemporaryDirectory() as tmp:
            t = time.perf_counter()
            result = run_study(STUDY, out or Path(tmp) / "out", quiet=True, track="off" if quick else None,
                               force=out is not None)
            total = time.perf_counter() - t
    finally:
        os.environ.clear()
        os.environ.update(env)
    r = result.results
    block = r["added_targets"]
    lines += [
        "",
        f"Whole study (`cadfeat run studies/nema17_add_targets.toml`{', check off' if quick else ''}): "
        f"{total:.1f} s wall (load average at the benchmark's start {load0[0]:.1f}, at the end "
        f"{os.getloadavg()[0]:.1f}: other jobs on the 2 cores lengthen every wall time here).",
        "",
        "| phase | wall time (s) |",
        "|---|---:|",
    ]
    lines += [f"| {name} | {sec:.2f} |" for name, sec in r["timings_s"].items()]
    p = block["predicted"]
    lines += [
        "",
        f"Predicted RMS pose error (mm): original {p['original']['error_mm']:.4f}, move-only optimum "
        f"{p['move_only']['error_mm']:.4f}, with {block['recommended']} added hole(s) {p['added']['error_mm']:.4f} "
        f"({100 * block['drop_vs_move_only']:.0f} % below the move-only optimum). Curve: "
        + ", ".join(f"{k}: {e:.4f}" for k, e in zip(block["curve"]["added"], block["curve"]["error_mm"], strict=True))
        + f". Requirements hold on the B-rep and the STEP: {block['requirements_hold']}.",
    ]
    holes = ", ".join(f"{h['name']} at ({', '.join(f'{v:.1f}' for v in h['centre'])})" for h in block["holes"])
    lines += [f"Added holes: {holes}; optimised.step holds them (re-imported, every hole found where it was put, "
              f"largest error {block['step']['max_error_mm']:.1e} mm), move_only.step the move-only optimum.", ""]
    lines += _tracking_lines(r)
    return save_section("bench_add_targets", "\n".join(lines))


if __name__ == "__main__":
    args = sys.argv[1:]
    print(main(quick="--quick" in args, out=Path(args[args.index("--out") + 1]) if "--out" in args else None))
