"""Per-target and per-frame state of the dual tracker (frozen; every step makes new ones)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from statistics import median

import numpy as np

from pipeline.stages import kalman
from pipeline.stages.appearance import AppearanceModel
from pipeline.stages.contour import LevelSetMemory
from pipeline.stages.detection import Background
from pipeline.types import BBox, TargetStatus

History = tuple[tuple[float, float, float, float, float], ...]
"""Recent clean measurements ``(frame, cx, cy, w, h)``, oldest first."""

BackgroundSource = Background | Callable[[], Background | None] | None
"""The detector's background of a frame: the sequence's, a function of no arguments returning
it (read only when the whole-frame search runs), or None (each frame's own)."""


def held(status: TargetStatus, partial: bool) -> bool:
    """Whether a frame with this outcome is no clean measurement of a target in view: any status
    but ``tracking``, or a measurement over a cut or collapsed contour (``partial``). After one,
    the next prediction holds the target's rates, the colour searches a wider region, and the
    frame joins no clean history."""
    return status != TargetStatus.TRACKING or partial


@dataclass(frozen=True)
class DualTarget:
    """One target: where it is, its models, and how long it has been missing.

    ``size`` is the kernel (w, h) of the next search (the paper's h); ``q`` the colour (or IR
    intensity) histogram of the mean-shift cue; ``appearance`` the correlation filter;
    ``app_size`` the size the filter's own scale estimate follows (no contour enters it, so a
    leaking or partial contour is measured against it); ``memory`` the last good level set and
    ``memory_center`` the target centre it was made at; ``entering`` the axes along which the
    first box was cut by the frame's border (the target walks in, and its size on that axis is
    what its clean contour says once it is inside); ``history`` the recent clean
    measurements; ``last_update`` the colour model's last update decision; ``split_frame``
    the frame of its last split from a group (re-merge hysteresis); ``case`` its last
    decision's case; ``speed`` how far it moved a frame over its last clean measurements, px
    (kept while its history is too short to tell: after it was found again); ``partial``
    whether its last measurement was over a cut or collapsed contour; ``empty_starts`` how
    many cold-started level sets running found nothing, the last at frame ``empty_start_frame``
    (``contour.retry_empty_frames``); ``part`` the size of the warm part of it that its IR
    contour shows, as shares of its box's width and height (``contour.warm_part``), None where
    the contour is the whole target; ``first_model`` its filter as trained on its first frame
    (or on the frame it had walked in whole by), which the search for it when missing also
    tries (``redetect.first_model``).
    """

    id: int
    box: BBox
    size: tuple[float, float]
    q: np.ndarray
    status: TargetStatus
    kf: kalman.GaussianState
    memory: LevelSetMemory | None = None
    memory_center: tuple[float, float] = (0.0, 0.0)
    history: History = ()
    missing: int = 0
    last_update: str = "none"
    split_frame: int = -1_000_000
    appearance: AppearanceModel | None = None
    app_size: tuple[float, float] = (0.0, 0.0)
    entering: tuple[bool, bool] = (False, False)
    case: str = "init"
    speed: float = 0.0
    partial: bool = False
    empty_starts: int = 0
    empty_start_frame: int = -1
    part: tuple[float, float] | None = None
    first_model: AppearanceModel | None = None

    @property
    def held(self) -> bool:
        """Its last frame was no clean measurement of it in view (:func:`held`)."""
        return held(self.status, self.partial)

    @property
    def reference_size(self) -> tuple[float, float]:
        """(w, h) in its recent clean frames (median), or its current size."""
        if len(self.history) >= 3:
            return median(r[3] for r in self.history), median(r[4] for r in self.history)
        return self.size

    @property
    def reference_area(self) -> float:
        """Box area in its recent clean frames (median), or of its current size."""
        if len(self.history) >= 3:
            return median(r[3] * r[4] for r in self.history)
        return self.size[0] * self.size[1]


@dataclass(frozen=True)
class GroupMemory:
    """The level set of a merged group, kept for the next frame's warm start, and its
    foreground member."""

    members: tuple[int, ...]
    memory: LevelSetMemory
    center: tuple[float, float]
    foreground: int


@dataclass(frozen=True)
class DualState:
    """Every target, the mode (``dual``: both channels, ``ir`` or ``visible``: one), the merged
    groups and the detector's background of the frame (:data:`BackgroundSource`)."""

    targets: tuple[DualTarget, ...]
    mode: str
    groups: tuple[GroupMemory, ...] = ()
    background: BackgroundSource = None
