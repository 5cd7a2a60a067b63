"""The dual tracker's lifecycle: when a coasting target is lost, the confidence each status
reports, and its status events, which the lifecycle every engine shares names
(:func:`pipeline.trackers.lifecycle.transition`)."""

from __future__ import annotations

from dataclasses import dataclass

from pipeline.tracker_config import LifecycleConfig
from pipeline.trackers.dual.decide import Case, Decision, Evidence, Rule, decision
from pipeline.trackers.lifecycle import transition
from pipeline.types import Event, TargetStatus


@dataclass(frozen=True)
class Lifecycle:
    """Statuses over frames.

    Parameters
    ----------
    cfg : LifecycleConfig
        ``dual.lifecycle``: how long a target may go without a measurement, and the ``conf``
        of each status.
    """

    cfg: LifecycleConfig

    def settle(self, d: Decision, ev: Evidence) -> Decision:
        """A coast whose prediction has left the frame, or that has gone on for more than
        ``max_missing_frames``, is the target lost (``LEFT_THE_FRAME``, ``MISSING_TOO_LONG``);
        any other decision stands."""
        if d.case != Case.COAST:
            return d
        missing = ev.missing + 1
        if ev.outside:
            return decision(Case.LOST, Rule.LEFT_THE_FRAME, status=TargetStatus.LOST)
        if missing > self.cfg.max_missing_frames:
            return decision(
                Case.LOST, Rule.MISSING_TOO_LONG, status=TargetStatus.LOST, missing=missing
            )
        return d

    def merged_status(self, missing: int) -> TargetStatus:
        """The status of a group member placed without a measurement for ``missing`` frames."""
        return TargetStatus.LOST if missing > self.cfg.max_missing_frames else TargetStatus.MERGED

    def confidence(self, status: TargetStatus) -> float:
        """``conf`` of a target in ``status`` (0 for a lost one)."""
        cfg = self.cfg
        return {
            TargetStatus.TRACKING: cfg.confidence_tracking,
            TargetStatus.OCCLUDED_PARTIAL: cfg.confidence_partial,
            TargetStatus.OCCLUDED_SEVERE: cfg.confidence_severe,
        }.get(status, 0.0)

    @staticmethod
    def events(
        tid: int, old: TargetStatus, d: Decision, contour_reason: str | None
    ) -> list[Event]:
        """The event of target ``tid``'s status moving from ``old`` to ``d.status``
        (:func:`pipeline.trackers.lifecycle.transition`), the decision's reason in brackets (and
        the contour's at an occlusion's start)."""
        new = d.status
        if new == old:
            return []
        why = d.why
        if new == TargetStatus.LOST:
            why = d.why.replace("-", " ")
        elif new.is_occluded and old != TargetStatus.LOST:
            why = f"{d.why}, contour {contour_reason or 'none'}"
        return list(transition(tid, old, new, why))

    @staticmethod
    def joined(tid: int, old: TargetStatus, group: str, where: str) -> list[Event]:
        """The event of target ``tid`` joining (or staying in) a merged ``group`` (``T1+T2``),
        ``where`` in it (in front, hidden)."""
        return list(transition(tid, old, TargetStatus.MERGED, f"in {group}, {where}"))

    @staticmethod
    def lost_in_group(tid: int, old: TargetStatus, missing: int) -> list[Event]:
        """The event of a group member given up after ``missing`` frames hidden in the group."""
        why = f"hidden in a merge for {missing} frames"
        return list(transition(tid, old, TargetStatus.LOST, why))
