"""Calibration boards: a chessboard or a ChArUco board, their corners in the board frame, detection and images.

A board is given by its *inner* corners (``cols x rows``, e.g. 9x6: the chessboard then has 10x7 squares), its
square size (mm) and, for ChArUco, the marker size (mm) and the ArUco dictionary. The board frame has its origin
at the outer top-left corner of the printed squares, x along the rows (to the right), y down the columns, z into
the board (so the z axis is the board's normal pointing away from a camera that sees it): board corner (i, j)
is at ((i + 1) s, (j + 1) s, 0) mm. ``board_image`` draws the board exactly as ``detect`` expects it (ChArUco
through ``cv2.aruco.CharucoBoard.generateImage``, OpenCV 4.6+ layout).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cadfeat.errors import CadfeatError

#: Board kinds ``--board`` accepts.
BOARD_KINDS = ("chessboard", "charuco")
#: The ArUco dictionary of a ChArUco board unless one is named (4x4 bits: the easiest to read when small).
DEFAULT_DICTIONARY = "DICT_4X4_250"
#: Fewest ChArUco corners a view must show (a homography and more; ``cv2.aruco`` interpolation needs markers).
MIN_CHARUCO_CORNERS = 8
#: A ChArUco marker's side over the square's unless given (see ``BoardSpec``).
MARKER_RATIO = 0.5


class BoardError(CadfeatError):
    """A board definition is invalid; the message names the option and what is allowed."""


@dataclass(frozen=True)
class BoardSpec:
    """A calibration board: ``kind`` ("chessboard" | "charuco"), ``cols`` x ``rows`` inner corners, ``square_mm``,
    for ChArUco ``marker_mm`` and ``dictionary`` (an ``cv2.aruco.DICT_*`` name). ``marker_mm`` defaults to half the
    square, as OpenCV's tutorial board: markers close to the chessboard corners bias the corners' sub-pixel
    refinement (measured on rendered 640x480 views: 0.09 px RMS at 0.5, 0.11 at 0.6, 0.16 at 0.75)."""

    kind: str
    cols: int
    rows: int
    square_mm: float
    marker_mm: float | None = None
    dictionary: str = DEFAULT_DICTIONARY

    def __post_init__(self) -> None:
        if self.kind not in BOARD_KINDS:
            raise BoardError(f"--board: {self.kind!r} is not allowed; allowed: {', '.join(BOARD_KINDS)}")
        if self.cols < 2 or self.rows < 2:
            raise BoardError(f"--inner-corners: {self.cols}x{self.rows} is not allowed; allowed: COLSxROWS, "
                             "both >= 2 (inner corners, e.g. 9x6)")
        if not self.square_mm > 0:
            raise BoardError(f"--square-mm: {self.square_mm} is not allowed; allowed: a length > 0 (mm)")
        if self.kind == "charuco":
            marker = MARKER_RATIO * self.square_mm if self.marker_mm is None else self.marker_mm
            if not 0 < marker < self.square_mm:
                raise BoardError(f"--marker-mm: {marker} is not allowed; allowed: 0 < marker < square "
                                 f"({self.square_mm} mm)")
            object.__setattr__(self, "marker_mm", float(marker))
            self.aruco_dictionary()  # checks the name and the marker count

    @property
    def squares(self) -> tuple[int, int]:
        """(squares across, squares down) of the printed board."""
        return self.cols + 1, self.rows + 1

    @property
    def size_mm(self) -> tuple[float, float]:
        """(width, height) of the printed squares, mm."""
        return self.squares[0] * self.square_mm, self.squares[1] * self.square_mm

    def describe(self) -> str:
        """One line: kind, corners, square (and marker) size."""
        text = f"{self.kind} {self.cols}x{self.rows} inner corners, {self.square_mm:g} mm squares"
        if self.kind == "charuco":
            text += f", {self.marker_mm:g} mm markers ({self.dictionary})"
        return text

    def corners_mm(self) -> np.ndarray:
        """(cols·rows, 3) every inner corner in the board frame, mm, in OpenCV's order (row by row)."""
        j, i = np.mgrid[0:self.rows, 0:self.cols]
        xy = np.stack([(i.ravel() + 1) * self.square_mm, (j.ravel() + 1) * self.square_mm], axis=-1)
        return np.column_stack([xy, np.zeros(len(xy))]).astype(np.float64)

    # ------------------------------------------------------------------ ChArUco
    def aruco_dictionary(self) -> Any:
        """The ``cv2.aruco.Dictionary`` named by ``dictionary``."""
        import cv2

        name = self.dictionary.upper()
        if not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
            allowed = sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))
            raise BoardError(f"--dictionary: {self.dictionary!r} is not allowed; allowed: {', '.join(allowed)}")
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
        need = (self.squares[0] * self.squares[1]) // 2
        if dictionary.bytesList.shape[0] < need:
            raise BoardError(f"--dictionary: {name} has {dictionary.bytesList.shape[0]} markers, the board needs "
                             f"{need}; allowed: a dictionary with >= {need} markers (e.g. DICT_4X4_250)")
        return dictionary

    def charuco_board(self) -> Any:
        """The ``cv2.aruco.CharucoBoard`` (lengths in mm)."""
        import cv2

        return cv2.aruco.CharucoBoard(self.squares, float(self.square_mm), float(self.marker_mm or 0.0),
                                      self.aruco_dictionary())

    # ------------------------------------------------------------------ detection
    def detect(self, grey: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
        """The board in a (H, W) uint8 image: (image points (n, 2) px, board points (n, 3) mm), or the reason
        it was not found (a sentence)."""
        return self._detect_charuco(grey) if self.kind == "charuco" else self._detect_chessboard(grey)

    def _detect_chessboard(self, grey: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
        """The classic ``cv2.findChessboardCorners`` finds the board (``cv2.findChessboardCornersSB``, more robust
        to blur and clutter, as fallback), then ``cv2.cornerSubPix`` refines each corner in a window of ~0.3
        square (measured on rendered tilted views: 0.095 px RMS and 0.26 px worst against 0.115 / 0.78 for the
        SB detector's own refinement). The refinement sets the accuracy, so the finder is only the start: the
        classic one takes 2-6 ms on a 1280x1024 board image, SB 0.12 s, and SB with ``CALIB_CB_ACCURACY`` 0.55 s
        (benchmarks/bench_real_cell.py)."""
        import cv2

        size = (self.cols, self.rows)
        found, corners = cv2.findChessboardCorners(grey, size, flags=cv2.CALIB_CB_ADAPTIVE_THRESH
                                                   | cv2.CALIB_CB_NORMALIZE_IMAGE)
        if not found:
            found, corners = cv2.findChessboardCornersSB(grey, size)
        if not found:
            return f"no {self.cols}x{self.rows} chessboard found (all inner corners must be visible)"
        px = np.asarray(corners, np.float32).reshape(self.rows, self.cols, 2)
        spacing = float(np.median(np.linalg.norm(np.diff(px, axis=1), axis=-1)))
        half = int(np.clip(round(0.3 * spacing), 2, 11))
        criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
        refined = cv2.cornerSubPix(grey, px.reshape(-1, 1, 2).copy(), (half, half), (-1, -1), criteria)
        return np.asarray(refined, np.float64).reshape(-1, 2), self.corners_mm()

    def _detect_charuco(self, grey: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
        import cv2

        board = self.charuco_board()
        corners, ids, _, marker_ids = cv2.aruco.CharucoDetector(board).detectBoard(grey)
        n = 0 if ids is None else len(ids)
        if n < MIN_CHARUCO_CORNERS:
            markers = 0 if marker_ids is None else len(marker_ids)
            return (f"only {n} ChArUco corners found ({markers} markers); "
                    f"needs >= {MIN_CHARUCO_CORNERS}")
        if board.checkCharucoCornersCollinear(ids):
            return "the ChArUco corners found lie on one line"
        ids = np.asarray(ids).ravel()
        # OpenCV's board frame has its origin at the outer top-left corner: the same as ours
        obj = np.asarray(board.getChessboardCorners(), np.float64)[ids]
        return np.asarray(corners, np.float64).reshape(-1, 2), obj

    # ------------------------------------------------------------------ images
    def board_image(self, px_per_square: int) -> np.ndarray:
        """The printed squares as a (H, W) uint8 image, ``px_per_square`` pixels per square (white 255,
        black 0), no margin: pixel (u, v) covers board x ∈ [u, u+1)·s/px_per_square mm (same for y)."""
        sx, sy = self.squares
        if self.kind == "charuco":
            return self.charuco_board().generateImage((sx * px_per_square, sy * px_per_square), marginSize=0,
                                                      borderBits=1)
        i, j = np.meshgrid(np.arange(sx), np.arange(sy))
        cells = np.where((i + j) % 2 == 0, 0, 255).astype(np.uint8)
        return np.kron(cells, np.ones((px_per_square, px_per_square), np.uint8))


def parse_corners(text: str) -> tuple[int, int]:
    """``--inner-corners`` "9x6" → (9, 6); one clear error otherwise."""
    parts = text.lower().replace("×", "x").split("x")
    try:
        cols, rows = (int(p) for p in parts)
    except ValueError:
        raise BoardError(f"--inner-corners: {text!r} is not allowed; allowed: COLSxROWS, e.g. 9x6") from None
    return cols, rows
