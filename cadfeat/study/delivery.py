"""What a study run hands its export, report and closed-loop check besides results.json (``pipeline.compute``):
the original and the delivered design (solid and holes), their set-ups, the move-only optimum when the delivered
design has added target holes (issue 31, ``study.added_design``) and the closed-loop check's workers (issue 17).

``Delivery`` is made once, at the end of ``compute``; the workers are started before it (the original's beside
the optimiser), so they live in a ``TrackingWorkers`` of their own that ``compute`` cancels when a phase fails.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.cad.sandbox import BackgroundCall
    from cadfeat.study.setup import StudySetup
    from cadfeat.study.tracking import Tracked

__all__ = ["AddedDesign", "Delivery", "MoveOnly", "TrackingWorkers"]


@dataclass
class TrackingWorkers:
    """The closed-loop check's worker per design (``closed_loop_check.start_design``; None: not started — mode
    ``off``, too few holes, or the check tracks that design itself). ``move_only``: with ``[add_targets]`` the
    move-only optimum, started before the added-target phase says whether it is the delivered design
    (``pipeline._add_targets``: it becomes ``after`` when no hole is recommended)."""

    before: BackgroundCall[Tracked] | None = None
    after: BackgroundCall[Tracked] | None = None
    move_only: BackgroundCall[Tracked] | None = None

    def pending(self, names: Collection[str] = ("before", "after", "move_only")
                ) -> dict[str, BackgroundCall[Tracked] | None]:
        """{design name: its worker or None} of the designs ``names``."""
        workers = {"before": self.before, "after": self.after, "move_only": self.move_only}
        return {name: worker for name, worker in workers.items() if name in names}

    def cancel(self) -> None:
        """Stop the workers that were started (those already collected have finished)."""
        for worker in (self.before, self.after, self.move_only):
            if worker is not None:
                worker.cancel()


@dataclass(frozen=True)
class AddedDesign:
    """The move-only optimum with the added target holes (``added_targets.run_phase``; the delivered design when
    holes are recommended, ``added_design.deliver``): its solid, its holes (the ``n_old`` holes it had first, then
    the added ones)."""

    shape: Shape
    holes: Sequence[Hole]
    n_old: int


@dataclass(frozen=True)
class MoveOnly:
    """The move-only optimum (solid and holes) when the delivered design is it with added target holes."""

    shape: Shape
    holes: Sequence[Hole]


@dataclass(frozen=True)
class Delivery:
    """A run's designs for the export (``verify.export_and_verify``), the report (``run._report_context``) and the
    closed-loop check (``closed_loop_check.attach``).

    ``shape0``/``holes0``: the original (the part as it is); ``shape1``/``holes1``: the delivered design (its CAD
    rebuild; with added target holes, the move-only optimum with them drilled: ``study.added_design``);
    ``setup``: the set-up the delivered design was optimised in (the integer combination that won), ``base``: the
    original's; ``move_only``: the move-only optimum when the delivered design has added holes (None otherwise);
    ``n_old``: how many of ``holes1`` are the part's (the first ones; the rest are added), None without added holes;
    ``workers``: the closed loop's workers tracking the designs meanwhile."""

    shape0: Shape
    holes0: Sequence[Hole]
    shape1: Shape
    holes1: Sequence[Hole]
    setup: StudySetup
    base: StudySetup
    move_only: MoveOnly | None = None
    n_old: int | None = None
    workers: TrackingWorkers = field(default_factory=TrackingWorkers)

    def designs(self) -> dict[str, tuple[Shape, Sequence[Hole]]]:
        """The designs the closed-loop check tracks: "before" (the original), "after" (the delivered design) and
        "move_only" (the move-only optimum) when the delivered design has added target holes."""
        out = {"before": (self.shape0, self.holes0), "after": (self.shape1, self.holes1)}
        if self.move_only is not None:
            out["move_only"] = (self.move_only.shape, self.move_only.holes)
        return out
