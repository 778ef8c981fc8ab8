"""The axiomatic design matrix (thesis §2.2.4, eq. 2.1–2.2; Suh's independence axiom).

Rows: the functional requirements — each objective (g_FOV, g_FOC, g_RES, g_DIR) and, with
``rows="all"``, each kind of kept requirement (edge, keepout, ligament, symmetry, volume, thresholds).
Columns: the design-parameter groups (``DesignSpace.groups()``: positions, diameters, other) or every
variable (``columns="variables"``). Entry (i, J) = ‖∂f_i/∂u_J‖₂, the sensitivity of requirement i to the
variables of column J in unit coordinates u = x/range (central finite differences); for a kind of kept
requirement, the largest over its individual margins. An entry is *significant* when it exceeds
``threshold_rel`` × the largest entry of its row (rows are thresholded relative to their own scale).

Verdict on the significant (binary) matrix, rows affected by nothing left out:

- ``uncoupled``: a permutation makes it diagonal — each row depends on exactly one column and no column
  drives two rows;
- ``decoupled``: a permutation makes it triangular — repeatedly a row depends on exactly one remaining
  column, which is then fixed (removed);
- ``coupled``: otherwise; in particular when more requirements than parameter groups depend on the
  parameters (Suh's Theorem 1), which is common with all kept requirements as rows — use
  ``columns="variables"`` or ``rows="objectives"`` for a finer picture.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.design.problem import Problem
    from cadfeat.results import JsonDict

__all__ = ["VERDICTS", "DesignMatrix", "classify", "design_matrix"]

VERDICTS = ("uncoupled", "decoupled", "coupled")


@dataclass
class DesignMatrix:
    """Rows (requirements), columns (parameter groups), sensitivities ``matrix`` (R, C) ≥ 0, the significant
    entries ``binary``, the relative threshold, the verdict and a note explaining it."""

    rows: list[str]
    cols: list[str]
    matrix: np.ndarray
    binary: np.ndarray
    threshold_rel: float
    verdict: str
    note: str

    def to_dict(self) -> JsonDict:
        return {"rows": list(self.rows), "cols": list(self.cols), "matrix": self.matrix.tolist(),
                "significant": self.binary.astype(int).tolist(), "threshold_rel": self.threshold_rel,
                "verdict": self.verdict, "note": self.note}


def classify(binary: np.ndarray) -> tuple[str, str]:
    """Verdict ("uncoupled" | "decoupled" | "coupled") and a note for a significant-entry matrix (R, C)."""
    A = np.asarray(binary, dtype=bool)
    active = A.any(axis=1)
    A = A[active]
    if A.shape[0] == 0:
        return "uncoupled", "no requirement depends on the parameters"
    r, c = A.shape
    n_cols_used = int(A.any(axis=0).sum())
    if r > n_cols_used:
        return "coupled", (f"{r} requirements depend on only {n_cols_used} parameter groups (Suh's Theorem 1: "
                           "fewer parameters than requirements means a coupled design)")
    if np.all(A.sum(axis=1) == 1) and np.all(A.sum(axis=0) <= 1):
        return "uncoupled", "each requirement depends on one parameter group of its own (diagonal)"
    rows, cols = set(range(r)), set(range(c))
    order: list[tuple[int, int]] = []
    while rows:
        pick = next(((i, j) for i in sorted(rows) for j in [np.flatnonzero(A[i, sorted(cols)])]
                     if len(j) == 1), None)
        if pick is None:
            return "coupled", "no ordering of the parameter groups makes the matrix triangular"
        i, j = pick
        col = sorted(cols)[int(j[0])]
        order.append((i, col))
        rows.remove(i)
        cols.remove(col)
    return "decoupled", ("triangular after permutation: set the parameter groups in the order "
                         f"{[c for _, c in order]} (column indices)")


def design_matrix(problem: Problem, x: np.ndarray, *, columns: str = "groups", rows: str = "all",
                  threshold_rel: float = 0.05, step: float = 1e-4) -> DesignMatrix:
    """The design matrix of ``problem`` at design ``x`` (module docstring). ``step``: finite-difference step
    as a fraction of each variable's range."""
    from cadfeat.design.optimize.evaluator import Evaluator  # lazy: would import pydantic at module load

    space = problem.space
    ev = Evaluator(problem, np.asarray(x, dtype=float))
    _, _, dG, dC = ev.gradients(ev.to_u(x), step)
    dG = dG / problem.scales[:, None]
    if columns == "variables":
        groups = {n: [i] for i, n in enumerate(space.names)}
    else:
        groups = space.groups()
    cols = list(groups)
    row_names = list(problem.names)
    S: list[list[float]] = [[float(np.linalg.norm(dG[i, idx])) for idx in groups.values()]
                            for i in range(len(row_names))]
    if rows == "all":
        kinds = problem.constraint_kinds()
        for kind in dict.fromkeys(kinds):
            sel = [k for k, name in enumerate(kinds) if name == kind]
            row_names.append(kind)
            S.append([float(np.max(np.linalg.norm(dC[sel][:, idx], axis=1))) for idx in groups.values()])
    A = np.array(S, dtype=float).reshape(len(row_names), len(cols))
    row_max = A.max(axis=1, keepdims=True)
    binary = (A > threshold_rel * row_max) & (row_max > 1e-12)
    verdict, note = classify(binary)
    zero = [row_names[i] for i in np.flatnonzero(~binary.any(axis=1))]
    if zero:
        note += f"; not affected by the parameters: {', '.join(zero)}"
    return DesignMatrix(row_names, cols, A, binary, threshold_rel, verdict, note)
