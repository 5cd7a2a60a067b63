"""The dual tracker's lifecycle: when a coasting target is lost, the events of a status change,
and the confidence each status reports."""

from __future__ import annotations

from dataclasses import dataclass

from pipeline.tracker_config import LifecycleConfig
from pipeline.trackers.dual.decide import Case, Decision, Evidence, Rule, decision
from pipeline.types import Event, EventKind, TargetStatus


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
        """The event of target ``tid``'s status changing from ``old`` to ``d.status``: lost,
        re-acquired, an occlusion's start or end (none when it stays)."""
        new = d.status
        if new == old:
            return []
        if new == TargetStatus.LOST:
            return [Event(EventKind.LOST, f"T{tid} lost ({d.why.replace('-', ' ')})", (tid,))]
        if old == TargetStatus.LOST:
            return [Event(EventKind.REACQUIRED, f"T{tid} re-acquired ({d.why})", (tid,))]
        if new.is_occluded and not old.is_occluded:
            text = f"T{tid} {new} ({d.why}, contour {contour_reason or 'none'})"
            return [Event(EventKind.OCCLUSION_START, text, (tid,))]
        if not new.is_occluded and old.is_occluded:
            return [Event(EventKind.OCCLUSION_END, f"T{tid} visible again ({d.why})", (tid,))]
        return []

    @staticmethod
    def lost_in_group(tid: int, old: TargetStatus, missing: int) -> list[Event]:
        """The event of a group member given up after ``missing`` frames hidden in the group."""
        if old == TargetStatus.LOST:
            return []
        text = f"T{tid} lost (hidden in a merge for {missing} frames)"
        return [Event(EventKind.LOST, text, (tid,))]
