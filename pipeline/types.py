"""Shared value types and the one geometry convention of dualtrack.

Geometry convention (docs/formats.md, written down once here):

* Images are numpy arrays indexed ``[row, col]`` = ``[y, x]``; visible frames are
  ``(H, W, 3)`` uint8 **BGR** (OpenCV order), infrared frames ``(H, W)`` uint8 after
  normalization (the raw array, possibly uint16, is kept beside it).
* Geometry is in continuous pixel coordinates ``(x, y)`` with ``x`` the column: the
  top-left corner of the top-left pixel is ``(0, 0)``, so the centre of pixel
  ``[r, c]`` is ``(c + 0.5, r + 0.5)``.
* Boxes are :class:`BBox` ``(x, y, w, h)`` floats in px; the box spans
  ``[x, x + w) x [y, y + h)`` and its centre is ``(x + w/2, y + h/2)``.
* Contours are ``(K, 2)`` float arrays of ``(x, y)`` px.
* Frame numbers start at 1 everywhere (files, results, the .rrd ``frame`` timeline).
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

FloatImage = NDArray[np.float32]
"""(H, W) float32 image."""
GrayImage = NDArray[np.uint8]
"""(H, W) uint8 image."""
BgrImage = NDArray[np.uint8]
"""(H, W, 3) uint8 image in OpenCV's BGR order."""
Points = NDArray[np.float64]
"""(K, 2) float array of (x, y) px."""


@dataclass(frozen=True, slots=True)
class BBox:
    """Axis-aligned box ``(x, y, w, h)`` in continuous 0-based px (see module doc).

    Parameters
    ----------
    x, y : float
        The top-left corner, px (the corner of the top-left pixel is (0, 0)).
    w, h : float
        Width and height, px; the box spans ``[x, x + w) x [y, y + h)``.

    Examples
    --------
    >>> b = BBox.from_center(50, 40, 20, 10)
    >>> b, b.area
    (BBox(x=40.0, y=35.0, w=20, h=10), 200)
    >>> round(b.iou(BBox(45, 35, 20, 10)), 3)  # shifted by a quarter of its width
    0.6
    >>> x, y, w, h = b  # a box unpacks, and is an array where one is asked for
    >>> import numpy as np
    >>> np.asarray(b).tolist()
    [40.0, 35.0, 20.0, 10.0]
    """

    x: float
    y: float
    w: float
    h: float

    @classmethod
    def from_center(cls, cx: float, cy: float, w: float, h: float) -> BBox:
        return cls(cx - w / 2.0, cy - h / 2.0, w, h)

    @classmethod
    def from_corners(cls, x1: float, y1: float, x2: float, y2: float) -> BBox:
        return cls(x1, y1, x2 - x1, y2 - y1)

    @property
    def cx(self) -> float:
        return self.x + self.w / 2.0

    @property
    def cy(self) -> float:
        return self.y + self.h / 2.0

    @property
    def center(self) -> tuple[float, float]:
        return (self.cx, self.cy)

    @property
    def area(self) -> float:
        return max(self.w, 0.0) * max(self.h, 0.0)

    @property
    def x2(self) -> float:
        return self.x + self.w

    @property
    def y2(self) -> float:
        return self.y + self.h

    def is_valid(self) -> bool:
        """True for a finite box with positive width and height."""
        return (
            all(math.isfinite(v) for v in (self.x, self.y, self.w, self.h))
            and self.w > 0
            and self.h > 0
        )

    def as_tuple(self) -> tuple[float, float, float, float]:
        return (self.x, self.y, self.w, self.h)

    def __iter__(self) -> Iterator[float]:
        """``x, y, w, h = box``."""
        return iter((self.x, self.y, self.w, self.h))

    def __array__(self, dtype: object = None, copy: object = None) -> np.ndarray:
        """``np.asarray(box)``: ``[x, y, w, h]`` float64."""
        return np.array(self.as_tuple(), dtype=dtype or np.float64)

    def shifted(self, dx: float, dy: float) -> BBox:
        return BBox(self.x + dx, self.y + dy, self.w, self.h)

    def scaled(self, factor: float) -> BBox:
        """Same centre, width and height multiplied by ``factor``."""
        return BBox.from_center(self.cx, self.cy, self.w * factor, self.h * factor)

    def times(self, factor: float) -> BBox:
        """Every coordinate times ``factor``: the box in the px of a frame ``factor`` times as
        large."""
        return BBox(self.x * factor, self.y * factor, self.w * factor, self.h * factor)

    def with_center(self, cx: float, cy: float) -> BBox:
        return BBox.from_center(cx, cy, self.w, self.h)

    def contains(self, x: float, y: float) -> bool:
        """Whether the point ``(x, y)`` lies inside the box or on its edge.

        >>> BBox(0, 0, 10, 5).contains(10, 2.5), BBox(0, 0, 10, 5).contains(10.5, 2.5)
        (True, False)
        """
        return self.x <= x <= self.x2 and self.y <= y <= self.y2

    def intersect(self, other: BBox) -> BBox:
        x1, y1 = max(self.x, other.x), max(self.y, other.y)
        x2, y2 = min(self.x2, other.x2), min(self.y2, other.y2)
        return BBox(x1, y1, max(x2 - x1, 0.0), max(y2 - y1, 0.0))

    def iou(self, other: BBox) -> float:
        """Intersection over union, in [0, 1]."""
        inter = self.intersect(other).area
        union = self.area + other.area - inter
        return min(max(inter / union, 0.0), 1.0) if union > 0 else 0.0

    def clip(self, width: int, height: int) -> BBox:
        """The part of the box inside a ``width`` x ``height`` frame (may be empty)."""
        return self.intersect(BBox(0.0, 0.0, float(width), float(height)))

    def to_cv(
        self, width: int | None = None, height: int | None = None
    ) -> tuple[int, int, int, int]:
        """Integer ``(x, y, w, h)`` for OpenCV calls (rounded, at least 1 px, inside the frame)."""
        x, y = round(self.x), round(self.y)
        w, h = max(round(self.w), 1), max(round(self.h), 1)
        if width is not None and height is not None:
            x = min(max(x, 0), width - 1)
            y = min(max(y, 0), height - 1)
            w = min(w, width - x)
            h = min(h, height - y)
        return (int(x), int(y), int(w), int(h))

    def __str__(self) -> str:
        return f"({self.x:.1f}, {self.y:.1f}, {self.w:.1f}, {self.h:.1f})"


class TargetStatus(enum.StrEnum):
    """Per-target status; the values are the names docs/formats.md lists.

    ``tentative`` (a detected target not yet confirmed), ``tracking``, ``occluded-partial``,
    ``occluded-severe`` (coasting on its motion), ``merged`` (inside a group of targets in
    mutual occlusion), ``lost``.

    Examples
    --------
    >>> TargetStatus("occluded-partial").is_occluded, TargetStatus.LOST.is_reported
    (True, False)
    """

    TENTATIVE = "tentative"
    TRACKING = "tracking"
    OCCLUDED_PARTIAL = "occluded-partial"
    OCCLUDED_SEVERE = "occluded-severe"
    MERGED = "merged"
    LOST = "lost"

    @property
    def is_reported(self) -> bool:
        """Whether tracks.csv carries a row for a target in this status."""
        return self not in (TargetStatus.TENTATIVE, TargetStatus.LOST)

    @property
    def is_occluded(self) -> bool:
        return self in (
            TargetStatus.OCCLUDED_PARTIAL,
            TargetStatus.OCCLUDED_SEVERE,
            TargetStatus.MERGED,
        )


class EventKind(enum.StrEnum):
    """Kinds of events written to the .rrd event log."""

    START = "start"
    MERGE = "merge"
    SPLIT = "split"
    OCCLUSION_START = "occlusion-start"
    OCCLUSION_END = "occlusion-end"
    LOST = "lost"
    REACQUIRED = "re-acquired"
    MODEL_FROZEN = "model-frozen"
    BIRTH = "birth"
    CONFIRMED = "confirmed"
    WARNING = "warning"


@dataclass(frozen=True, slots=True)
class DecisionLabel:
    """A tracker's decision in one frame, as the tracker's own enums: its case (what was measured,
    or that nothing was) and the rule that chose it, and ``why``, the rule's text with its details
    filled in (a contour's reason, a count of frames). ``str()`` is ``case:why``, as
    ``targets.csv`` and the recording write it.

    Examples
    --------
    >>> class Case(enum.StrEnum):
    ...     COAST = "coast"
    >>> class Rule(enum.StrEnum):
    ...     NO_EVIDENCE = "no-evidence"
    >>> d = DecisionLabel(Case.COAST, Rule.NO_EVIDENCE, "no-evidence")
    >>> str(d), d.case is Case.COAST
    ('coast:no-evidence', True)
    """

    case: enum.StrEnum
    rule: enum.StrEnum
    why: str

    def __str__(self) -> str:
        return f"{self.case.value}:{self.why}"


@dataclass(frozen=True, slots=True)
class Event:
    """Something that happened at a frame (merge, split, lost, ...)."""

    kind: EventKind
    text: str
    target_ids: tuple[int, ...] = ()


@dataclass(frozen=True, slots=True)
class InitTarget:
    """An initial target: its id and its box in the first frame."""

    id: int
    box: BBox


@dataclass(frozen=True)
class TargetResult:
    """What a tracker reports for one target at one frame.

    Parameters
    ----------
    id : int
        Track id (1..N for initialised targets).
    box : BBox
        Estimated box in frame px.
    status : TargetStatus
        Lifecycle status.
    source : str
        The stage that produced the box (``meanshift``, ``levelset``, ``kalman``,
        ``camshift``, ``opencv-mil``, ``merge-eq11``, ...).
    iterations : Mapping[str, int]
        Iterations spent per iterative stage this frame.
    rho : float
        Bhattacharyya coefficient of the appearance match (NaN when not computed).
    model_update : str
        The model-update decision and its reason, ``decision:reason``.
    confidence : float
        In [0, 1]; lower when occluded. Written as ``conf`` in tracks.csv.
    contour : list of Points
        Contours found by a level-set stage (frame px), possibly empty.
    diagnostics : Mapping[str, float]
        Named scalar diagnostics (``d``, ``area_px2``, ...).
    overlays : Mapping[str, BBox]
        Named auxiliary boxes to draw (``prediction``, ``search``), frame px.
    decision : DecisionLabel or None
        The tracker's decision for this frame (its case and rule as enums, and why; written
        ``case:why``, ``contour:contour-and-appearance``); None for trackers without one.

    Examples
    --------
    >>> r = TargetResult(1, BBox(10, 20, 30, 40), TargetStatus.TRACKING, "levelset")
    >>> r.status.is_reported, r.replace(status=TargetStatus.LOST).status.value
    (True, 'lost')
    """

    id: int
    box: BBox
    status: TargetStatus
    source: str
    iterations: Mapping[str, int] = field(default_factory=dict)
    rho: float = math.nan
    model_update: str = "none"
    confidence: float = 1.0
    contour: tuple[Points, ...] = ()
    diagnostics: Mapping[str, float] = field(default_factory=dict)
    overlays: Mapping[str, BBox] = field(default_factory=dict)
    decision: DecisionLabel | None = None

    def replace(self, **changes: object) -> TargetResult:
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]


class TruthMatch(enum.StrEnum):
    """How a target's output compares with its truth in one frame (the .rrd's
    ``targets/<id>/truth``)."""

    OVERLAP = "overlap"  # the output box overlaps the truth (IoU > 0)
    FAILURE = "failure"  # truth exists, but there is no output or it does not overlap (IoU 0)
    NO_TRUTH = "no-truth"  # no truth in this frame (not scored)


@dataclass(frozen=True)
class FrameTruth:
    """The ground truth of one frame and how the tracker's output scores against it (for the
    recording).

    ``boxes[channel][id]`` are the truth boxes; ``center_error_px``, ``iou`` and ``match`` are per
    target id that has both an output and truth this frame (``inf`` / 0 / failure when the
    target is not reported).
    """

    boxes: Mapping[str, Mapping[int, BBox]]
    center_error_px: Mapping[int, float] = field(default_factory=dict)
    iou: Mapping[int, float] = field(default_factory=dict)
    match: Mapping[int, TruthMatch] = field(default_factory=dict)


@dataclass(frozen=True)
class FrameResult:
    """Everything a tracker reports for one frame.

    Parameters
    ----------
    frame : int
        The frame number, from 1.
    targets : tuple of TargetResult
        One per target the tracker holds this frame.
    events : tuple of Event
        What happened (merges, splits, occlusions, losses, re-acquisitions, ...).
    stage_seconds : mapping of str to float
        Seconds spent per stage this frame.
    diagnostics : mapping of str to array
        Optional images (a detector's maps, ...).

    Examples
    --------
    >>> res = FrameResult(3, (TargetResult(2, BBox(0, 0, 5, 5), TargetStatus.TRACKING, "x"),))
    >>> res.target(2).box.center, res.target(9)
    ((2.5, 2.5), None)
    """

    frame: int
    targets: tuple[TargetResult, ...]
    events: tuple[Event, ...] = ()
    stage_seconds: Mapping[str, float] = field(default_factory=dict)
    diagnostics: Mapping[str, np.ndarray] = field(default_factory=dict)

    def target(self, target_id: int) -> TargetResult | None:
        for t in self.targets:
            if t.id == target_id:
                return t
        return None


def zoomed(result: FrameResult, factor: float) -> FrameResult:
    """``result`` with every frame-px quantity of its targets times ``factor``: boxes, contours,
    overlays, and the diagnostics whose names end in ``_px`` (times ``factor``) or ``_px2``
    (times its square); the rest (rates, ratios, counts, the diagnostic images) as they are.
    For a tracker run on frames ``factor`` times smaller than the source's.

    Examples
    --------
    >>> t = TargetResult(1, BBox(10.0, 20.0, 4.0, 6.0), TargetStatus.TRACKING, "x",
    ...                  diagnostics={"area_px2": 24.0, "psr": 9.0})
    >>> z = zoomed(FrameResult(1, (t,)), 2).targets[0]
    >>> z.box.as_tuple(), z.diagnostics["area_px2"], z.diagnostics["psr"]
    ((20.0, 40.0, 8.0, 12.0), 96.0, 9.0)
    """
    if factor == 1:
        return result

    def unit(name: str) -> float:
        return factor * factor if name.endswith("_px2") else factor if name.endswith("_px") else 1

    targets = tuple(
        dataclasses.replace(
            t,
            box=t.box.times(factor),
            contour=tuple(np.asarray(c, np.float64) * factor for c in t.contour),
            overlays={k: b.times(factor) for k, b in t.overlays.items()},
            diagnostics={k: v * unit(k) for k, v in t.diagnostics.items()},
        )
        for t in result.targets
    )
    return dataclasses.replace(result, targets=targets)
