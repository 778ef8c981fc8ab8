"""What a study run hands its export, report and closed-loop check besides results.json (``pipeline.compute``):
the original and the delivered design (solid and holes), their set-ups, the added-target design (issue 31) and the
closed-loop check's workers (issue 17).

``Delivery`` is made once, at the end of ``compute``; the workers are started before it (the original's beside
the optimiser), so they live in a ``TrackingWorkers`` of their own that ``compute`` cancels when a phase fails.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from cadquery import Shape

    from cadfeat.cad.features import Hole
    from cadfeat.cad.sandbox import BackgroundCall
    from cadfeat.study.setup import StudySetup

__all__ = ["AddedDesign", "Delivery", "TrackingWorkers"]


@dataclass
class TrackingWorkers:
    """The closed-loop check's worker per design (``closed_loop_check.start_design``; None: not started — mode
    ``off``, too few holes, or the check tracks that design itself)."""

    before: BackgroundCall | None = None
    after: BackgroundCall | None = None

    def pending(self) -> dict[str, BackgroundCall | None]:
        """{"before": worker or None, "after": worker or None}."""
        return {"before": self.before, "after": self.after}

    def cancel(self) -> None:
        """Stop the workers that were started (those already collected have finished)."""
        for worker in (self.before, self.after):
            if worker is not None:
                worker.cancel()


@dataclass(frozen=True)
class AddedDesign:
    """The delivered design with the added target holes (``added_targets.run_phase``): its solid, its holes (the
    ``n_old`` holes it had first, then the added ones)."""

    shape: Shape
    holes: Sequence[Hole]
    n_old: int


@dataclass(frozen=True)
class Delivery:
    """A run's designs for the export (``verify.export_and_verify``), the report (``run._report_context``) and the
    closed-loop check (``closed_loop_check.attach``, ``added_targets.confirm``).

    ``shape0``/``holes0``: the original (the part as it is); ``shape1``/``holes1``: the delivered design (its CAD
    rebuild); ``setup``: the set-up the delivered design was optimised in (the integer combination that won),
    ``base``: the original's; ``added``: the added-target design, None without ``[add_targets]``;
    ``workers``: the closed loop's workers tracking the two designs meanwhile."""

    shape0: Shape
    holes0: Sequence[Hole]
    shape1: Shape
    holes1: Sequence[Hole]
    setup: StudySetup
    base: StudySetup
    added: AddedDesign | None = None
    workers: TrackingWorkers = field(default_factory=TrackingWorkers)
