"""Benchmark: feature-pose evaluations per second of ``measures.evaluate`` (all measures at once).

Baseline, in the same file and the same process: a plain per-pose Python loop (numpy over the N features
of one pose) computing the same measures the straightforward way — the rim conic from
H = K [u v c] and ``numpy.linalg.inv``, the ellipse from ``eigh`` of its 2×2 block, the stacked (2N, 6)
Jacobian's ``numpy.linalg.svd`` for the diagnostics and ``numpy.linalg.pinv`` for Λ = 1/‖J⁺D‖ (eq. 4.32).
Single thread: OMP/OPENBLAS/MKL thread counts are set to 1 before numpy is imported (when this module is
the first to import it). Both implementations' results are compared (max differences in the notes).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import importlib.util  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from benchutil import save_section

SIZES = ((200, 8), (1000, 16), (10000, 64))
#: Extra row: the largest size with an ideal pinhole (no distortion terms).
PINHOLE_SIZE = (10000, 64)


def _machine() -> str:
    spec = importlib.util.spec_from_file_location("run_all", HERE / "run_all.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    threads = os.environ.get("OPENBLAS_NUM_THREADS", "?")
    return f"{module.machine_description()}, BLAS threads {threads}"


# ---------------------------------------------------------------------- baseline: a per-pose loop
def _rim_basis(axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.where(np.abs(axes[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(axes, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, np.cross(axes, u)


def baseline_evaluate(camera, T_cam_part, screws, centres, axes, radii, min_axis_px=5.0) -> dict[str, np.ndarray]:
    """The measures of ``measures.evaluate`` with a Python loop over poses (numpy over one pose's features)."""
    axes = axes / np.linalg.norm(axes, axis=1, keepdims=True)
    bu, bv = _rim_basis(axes)
    cos_half = np.cos(0.5 * camera.fov_rad)
    near, far = camera.depth_of_field_mm
    scale = 0.5 * (far - near) if np.isfinite(far) else near
    rows: dict[str, list] = {k: [] for k in ("fov", "fov_px", "focus", "resolution_px", "minor_axis_px", "facing",
                                             "visible", "centre_px", "axes_px", "sigma_min", "condition",
                                             "manipulability", "resolvability")}
    C0 = np.zeros((len(radii), 3, 3))
    C0[:, 0, 0] = C0[:, 1, 1] = 1.0
    C0[:, 2, 2] = -radii**2
    for k in range(len(T_cam_part)):
        R, t = T_cam_part[k, :3, :3], T_cam_part[k, :3, 3]
        P, n, u, v = centres @ R.T + t, axes @ R.T, bu @ R.T, bv @ R.T
        dist = np.linalg.norm(P, axis=1)
        rows["fov"].append(P[:, 2] / dist - cos_half)
        rows["focus"].append(np.minimum(P[:, 2] - near, far - P[:, 2]) / scale)
        facing = -np.sum(n * P, axis=1) / dist
        # rim conic C = H⁻ᵀ diag(1, 1, −R²) H⁻¹, H = [u v c] (normalised image), then the pixel ellipse
        Hinv = np.linalg.inv(np.stack([u, v, P], axis=2))
        C = np.transpose(Hinv, (0, 2, 1)) @ C0 @ Hinv
        A, b = C[:, :2, :2], C[:, :2, 2]
        x0 = -np.linalg.solve(A, b[:, :, None])[:, :, 0]
        kk = C[:, 2, 2] + np.sum(b * x0, axis=1)
        D = camera.distortion_jacobian(x0)
        Dinv = np.linalg.inv(D)
        M = np.transpose(Dinv, (0, 2, 1)) @ (A / -kk[:, None, None]) @ Dinv
        lam, _ = np.linalg.eigh(M)
        lam = np.clip(lam, 1e-300, None)
        ax = 2.0 / np.sqrt(lam)  # ascending eigenvalues: major axis first
        centre = camera.distort_normalized(x0)
        Minv = np.linalg.inv(M)
        half = np.sqrt(np.stack([Minv[:, 0, 0], Minv[:, 1, 1]], axis=1))
        fov_px = np.min(np.concatenate([centre - half, [camera.width, camera.height] - centre - half], axis=1), axis=1)
        valid = P[:, 2] - radii * np.sqrt(1 - n[:, 2] ** 2) > 1e-6
        visible = valid & (facing > 0) & (fov_px >= 0)
        rows["fov_px"].append(fov_px)
        rows["resolution_px"].append(ax[:, 1] - min_axis_px)
        rows["minor_axis_px"].append(ax[:, 1])
        rows["facing"].append(facing)
        rows["visible"].append(visible)
        rows["centre_px"].append(centre)
        rows["axes_px"].append(ax)
        # stacked image Jacobian (eq. 4.9–4.14) of the visible features, SVD diagnostics, pinv resolvability
        x, y, iz = P[:, 0] / P[:, 2], P[:, 1] / P[:, 2], 1.0 / P[:, 2]
        Lm = np.zeros((len(P), 2, 6))
        Lm[:, 0] = np.stack([-iz, 0 * iz, x * iz, x * y, -(1 + x * x), y], axis=1)
        Lm[:, 1] = np.stack([0 * iz, -iz, y * iz, 1 + y * y, -x * y, -x], axis=1)
        J = (camera.distortion_jacobian(np.stack([x, y], axis=1)) @ Lm)[visible].reshape(-1, 6)
        if J.shape[0] < 6:
            J = np.vstack([J, np.zeros((6 - J.shape[0], 6))])
        s = np.linalg.svd(J, compute_uv=False)
        rows["sigma_min"].append(s[-1])
        rows["condition"].append(s[0] / s[-1] if s[-1] > 1e-6 * s[0] else 1e12)
        rows["manipulability"].append(np.prod(s))
        flow = J @ screws[k]
        norm = np.linalg.norm(flow)
        rows["resolvability"].append(1.0 / np.linalg.norm(np.linalg.pinv(J, rcond=1e-6) @ (flow / norm))
                                     if norm > 0 else 0.0)
    return {k: np.array(v) for k, v in rows.items()}


# ---------------------------------------------------------------------- scenario
def scenario(L: int, N: int, seed: int = 0, pinhole: bool = False):
    """The thesis camera with its distortion (or without, ``pinhole``), N holes on a 90 mm plate (+z out of the
    material, axes tilted a little), L camera poses at 100-160 mm looking at the plate (some holes fall
    outside the image), random screws."""
    from cadfeat.camera import Camera
    from cadfeat.poses import invert_T, look_at

    rng = np.random.default_rng(seed)
    cam = Camera.preset("dalsa-cad1-128a").replace(focus_distance_mm=130.0)
    if pinhole:
        cam = cam.without_distortion()
    eyes = np.column_stack([rng.normal(0, 10, L), rng.normal(0, 10, L), rng.uniform(100, 160, L)])
    targets = rng.normal(0, 3, (L, 3))
    T_cam_part = invert_T(look_at(eyes, targets, up=(0.0, 1.0, 0.0)))
    centres = np.column_stack([rng.uniform(-45, 45, N), rng.uniform(-45, 45, N), rng.uniform(-3, 3, N)])
    axes = np.tile([0.0, 0.0, 1.0], (N, 1)) + rng.normal(0, 0.1, (N, 3))
    radii = rng.uniform(1.5, 4.0, N)
    screws = np.column_stack([rng.normal(0, 20, (L, 3)), rng.normal(0, 0.2, (L, 3))])
    return cam, T_cam_part, screws, centres, axes, radii


def _rates(fast, fast_evals: int, slow, slow_evals: int, min_time: float) -> tuple[float, float]:
    """Best rates (evals per CPU second) of two functions timed alternately, so both see the same load."""
    fast(), slow()
    best = [np.inf, np.inf]
    total = [0.0, 0.0]
    runs = 0
    while min(total) < min_time or runs < 3:
        for i, func in enumerate((fast, slow)):
            start = time.process_time()
            func()
            dt = time.process_time() - start
            best[i], total[i] = min(best[i], dt), total[i] + dt
        runs += 1
    return fast_evals / best[0], slow_evals / best[1]


def _agreement(fast, slow) -> dict[str, float]:
    out = {}
    for key in ("fov", "fov_px", "focus", "minor_axis_px", "facing", "sigma_min", "resolvability"):
        a, b = np.asarray(getattr(fast, key), float), np.asarray(slow[key], float)
        out[key] = float(np.max(np.abs(a - b) / np.maximum(1.0, np.abs(b))))
    out["visible"] = float(np.mean(np.asarray(fast.visible) != slow["visible"]))
    return out


def main(quick: bool = False) -> str:
    from cadfeat import measures

    rows, agreement, visible_frac = [], {}, []
    for L, N, pinhole in [(L, N, False) for L, N in SIZES] + [(*PINHOLE_SIZE, True)]:
        args = scenario(L, N, pinhole=pinhole)
        base_L = min(L, 300 if quick else 2000)  # the loop is linear in L: time a prefix of the poses
        base_args = (args[0], args[1][:base_L], args[2][:base_L], *args[3:])
        fast, slow = _rates(lambda a=args: measures.evaluate(*a), L * N, lambda a=base_args: baseline_evaluate(*a),
                            base_L * N, 0.3 if quick else 2.0)
        rows.append((L, N, fast, slow, pinhole))
        m = measures.evaluate(*base_args)
        visible_frac.append(float(m.visible.mean()))
        for k, v in _agreement(m, baseline_evaluate(*base_args)).items():
            agreement[k] = max(agreement.get(k, 0.0), v)
    lines = [
        "## Measures: all per-pose, per-feature measures at once (bench_measures)",
        "",
        f"Machine: {_machine()}; load average {os.getloadavg()[0]:.1f} at the start.",
        f"Rates from the best of repeated runs (≥ {0.3 if quick else 2.0} s each) in process CPU time (one thread),",
        "evaluate and baseline timed alternately so both see the same load of a shared machine.",
        "`evaluate` = `cadfeat.measures.evaluate` (FOV cone + image margin, focus, exact rim ellipse, resolution,",
        "facing, visibility, JᵀJ diagnostics, resolvability); baseline = per-pose Python loop in this file",
        "(numpy over the pose's features, `numpy.linalg.svd` + `numpy.linalg.pinv` on the (2N, 6) Jacobian),",
        "timed on the first ≤ 2000 poses (its cost is linear in L). Thesis camera with its lens distortion;",
        "the last row without distortion (ideal pinhole).",
        "",
        "| L poses | N features | evaluate (M evals/s) | per-pose loop (M evals/s) | speed-up |",
        "|---:|---:|---:|---:|---:|",
    ]
    lines += [f"| {L} | {N}{' (pinhole)' if p else ''} | {f / 1e6:.2f} | {s / 1e6:.3f} | {f / s:.0f}× |"
              for L, N, f, s, p in rows]
    met = [f"{L}×{N}{' pinhole' if p else ''}" for L, N, f, b, p in rows if f >= 2e6 and f / b >= 50]
    lines += [
        "",
        f"Targets (issue 2: ≥ 50× the loop and ≥ 2 M evals/s on one core) met together at: {', '.join(met) or 'none'}.",
        "`evaluate` runs its per-feature-pose work (conics, ellipses, margins, lens) and JᵀJ in compiled numba kernels",
        "(`cadfeat/measures/kernels.py`, compiled once and cached on disk; the first call in a process costs ≈ 0.6 s,",
        "excluded here); large pinhole batches keep numpy per-feature slabs (faster there). What remains: batched",
        "`eigvalsh` of the 6×6 JᵀJ at ≈ 2 µs per pose (LAPACK; hand-written",
        "tridiagonal-QL and Jacobi solvers were no faster), ≈ 130 ns per feature-pose of dependent divisions and",
        "square roots in the kernel, and the numpy frame transforms (BLAS products, kept for identical results).",
        "The loop baseline costs ≈ 0.7–1 ms per pose whatever N, so its rate grows with N.",
    ]
    lines += [
        "",
        "Agreement with the baseline (max relative difference, on the timed scenario; visible fraction "
        f"{min(visible_frac):.2f}–{max(visible_frac):.2f}): "
        + ", ".join(f"{k} {v:.1e}" for k, v in agreement.items()) + ".",
    ]
    return save_section("bench_measures", "\n".join(lines))


if __name__ == "__main__":
    print(main(quick="--quick" in sys.argv))
