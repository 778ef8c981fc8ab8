"""The calibration's figure (PNG beside the calibration file): per-image reprojection RMS, the residuals, and how
the board corners cover the image (uncovered corner regions shaded: the distortion is extrapolated there)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cadfeat.calibration.solve import CORNER_REGION, CalibrationResult

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes


def calibration_plot(result: CalibrationResult, path: str | Path) -> Path:
    """Draw the three panels of ``result`` into the PNG ``path``; returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_rms, ax_res, ax_cov) = plt.subplots(1, 3, figsize=(15, 4.6))
    _per_view(ax_rms, result)
    _residuals(ax_res, result)
    _coverage(ax_cov, result)
    fig.suptitle(f"{result.board.describe()}: {len(result.views)} images, RMS {result.rms_px:.3f} px, "
                 f"{len(result.rejected)} rejected")
    fig.tight_layout()
    fig.savefig(str(path), dpi=110)
    plt.close(fig)
    return Path(path)


def _per_view(ax: Axes, result: CalibrationResult) -> None:
    rms = [v.rms_px for v in result.views]
    ax.bar(np.arange(len(rms)), rms, color="tab:blue")
    ax.axhline(result.rms_px, color="k", ls="--", lw=1, label=f"overall {result.rms_px:.3f} px")
    ax.set_xlabel("image (order used)")
    ax.set_ylabel("reprojection RMS (px)")
    ax.set_title("per-image error")
    ax.legend(loc="upper right")


def _residuals(ax: Axes, result: CalibrationResult) -> None:
    for v in result.views:
        ax.plot(v.residuals_px[:, 0], v.residuals_px[:, 1], ".", ms=2)
    t = np.linspace(0, 2 * np.pi, 100)
    ax.plot(result.rms_px * np.cos(t), result.rms_px * np.sin(t), "k--", lw=1)
    ax.set_aspect("equal")
    ax.set_xlabel("residual u (px)")
    ax.set_ylabel("residual v (px)")
    ax.set_title("residuals (one colour per image; circle = RMS)")


def _coverage(ax: Axes, result: CalibrationResult) -> None:
    from matplotlib.patches import Rectangle

    cam, cov = result.camera, result.coverage
    for v in result.views:
        ax.plot(v.image_px[:, 0], v.image_px[:, 1], ".", ms=2)
    rx, ry = CORNER_REGION * cam.width, CORNER_REGION * cam.height
    origin = {"top-left": (0, 0), "top-right": (cam.width - rx, 0), "bottom-left": (0, cam.height - ry),
              "bottom-right": (cam.width - rx, cam.height - ry)}
    for name in cov.uncovered_corners:
        ax.add_patch(Rectangle(origin[name], rx, ry, color="tab:red", alpha=0.3))
    ax.add_patch(Rectangle((0, 0), cam.width, cam.height, fill=False, color="k"))
    ax.set_xlim(-5, cam.width + 5)
    ax.set_ylim(cam.height + 5, -5)
    ax.set_aspect("equal")
    ax.set_title(f"coverage: {cov.grid_fraction:.0%} of cells, radius {cov.radius_fraction:.0%}"
                 + (" (red: uncovered)" if cov.uncovered_corners else ""))
