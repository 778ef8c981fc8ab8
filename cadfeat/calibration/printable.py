"""The calibration board as a PDF to print at scale: the squares at their size in mm, the square size printed on the
page and a 100 mm check line (measure it after printing: printers scale pages to fit unless told not to)."""

from __future__ import annotations

from pathlib import Path

from cadfeat.calibration.boards import BoardSpec
from cadfeat.errors import CadfeatError

#: Paper sizes tried in turn (name, width, height in mm, portrait); each also landscape.
PAPERS = (("A4", 210.0, 297.0), ("A3", 297.0, 420.0), ("A2", 420.0, 594.0))
#: Blank margin around the board and the texts, mm.
MARGIN_MM = 15.0
#: Room below the board for the texts and the check line, mm.
FOOTER_MM = 28.0
MM_PER_INCH = 25.4


def page_for(board: BoardSpec) -> tuple[str, float, float]:
    """(name, width mm, height mm) of the smallest paper in ``PAPERS`` the board fits on with its footer."""
    bw, bh = board.size_mm
    for name, w, h in PAPERS:
        for pw, ph, orient in ((w, h, "portrait"), (h, w, "landscape")):
            if bw + 2 * MARGIN_MM <= pw and bh + 2 * MARGIN_MM + FOOTER_MM <= ph:
                return f"{name} {orient}", pw, ph
    raise CadfeatError(f"--square-mm: a {board.describe()} board is {bw:g} x {bh:g} mm, larger than A2; allowed: "
                       "smaller squares or fewer corners")


def board_pdf(board: BoardSpec, path: str | Path, px_per_square: int = 120) -> tuple[str, float, float]:
    """Write the board to print (PDF at 1:1) and return its paper (name, width mm, height mm). The board's top-left
    outer corner is at (MARGIN_MM, MARGIN_MM) from the page's top-left corner."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    name, pw, ph = page_for(board)
    fig = plt.figure(figsize=(pw / MM_PER_INCH, ph / MM_PER_INCH))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(0, pw)
    ax.set_ylim(ph, 0)
    ax.axis("off")
    bw, bh = board.size_mm
    x0 = y0 = MARGIN_MM
    ax.imshow(board.board_image(px_per_square), cmap="gray", vmin=0, vmax=255, interpolation="none",
              extent=(x0, x0 + bw, y0 + bh, y0))
    y = y0 + bh + 8.0
    ax.text(x0, y, f"{board.describe()}: square = {board.square_mm:g} mm"
            + (f", marker = {board.marker_mm:g} mm" if board.kind == "charuco" else ""), fontsize=9, va="center")
    y += 9.0
    ax.plot([x0, x0 + 100.0], [y, y], color="k", lw=0.8)
    for x in (x0, x0 + 50.0, x0 + 100.0):
        ax.plot([x, x], [y - 2.0, y + 2.0], color="k", lw=0.8)
    ax.text(x0 + 104.0, y, "100 mm: print at 100 % (actual size) and measure this line; measure a square too and "
            "give what you measure to --square-mm", fontsize=6.5, va="center")
    fig.savefig(str(path), format="pdf")
    plt.close(fig)
    return name, pw, ph
