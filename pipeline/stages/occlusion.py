"""Occlusion grading of the Kalman-CAMShift paper (Yan et al. 2014, §3.1), as small pure decisions.

* Bhattacharyya distance ``d = sqrt(1 - rho)`` below ``Tb`` (0.4), and a CamShift size
  that has not changed a lot: not occluded (the paper's experiment (a): "if the target
  size CamShift computes changes a lot, or d >= Tb, occlusion has occurred"; a change is
  "a lot" when the area exceeds ``max_area_growth`` times the predicted area;
  ``size_change_occludes`` turns the size test off).
* otherwise occluded; the CamShift area decides how badly: ``area >= min_area``
  partial, ``area < min_area`` severe, where ``min_area`` is 40 % of the smallest area
  measured in the first 20 unoccluded frames.
* More than ``K0`` consecutive severe frames: the target is lost.

Beyond the paper, :func:`nearer_overlapping` orders given boxes by depth (which may hide which)
where targets stand on one ground.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from pipeline.params import Section, param
from pipeline.types import BBox


@dataclass(frozen=True)
class OcclusionConfig(Section):
    """Occlusion grading (Kalman-CAMShift paper).

    Parameters
    ----------
    distance_threshold : float
        Tb: Bhattacharyya distance at or above which the target counts as occluded, in
        (0, 1]; default 0.4 (the paper's). Increasing it tolerates more appearance change
        before predicting instead of measuring.
    max_area_growth : float
        The CamShift area may grow to this many times the predicted box area before the
        size change counts as an occlusion (CamShift spreading onto an occluder of the
        target's colour), > 1; default 2. Increasing it follows faster approaches.
    min_area_fraction : float
        min_area = this x the smallest CamShift area of the reference frames, in (0, 1];
        default 0.4 (the paper's 40 %). Increasing it grades more occlusions as severe.
    reference_frames : int
        Unoccluded frames whose areas define min_area, >= 1; default 20 (the paper's).
    max_severe_frames : int
        K0: consecutive severe frames after which the target is declared lost, >= 1;
        default 50 (2 s at 25 frames/s; the paper leaves K0 open): longer than walking
        behind a pillar or a wall, shorter than having left the scene.
    search_scale : float
        Search window = predicted box x this while the target is seen, in [1, 5];
        default 1.5.
    missing_search_scale : float
        Search window = predicted box (with the last good size) x this while the target
        is severely occluded or lost, in [1, 10]; default 3. Increasing it re-acquires a
        target that re-appears further from its prediction, at more risk of locking on
        a look-alike.
    reacquire_distance : float
        Beyond the paper: a missing target is taken back only when d falls below this,
        in (0, 1], at most ``distance_threshold``; default 0.3. The gap to Tb is a
        hysteresis that stops a half-hidden target flapping between seen and hidden.
    rewind_frames : int
        Beyond the paper: when an occlusion starts, the motion estimate restarts from
        the clean measurements (d < Tb/2) of the last ``history_frames`` frames, if the
        newest is at most this many frames old, discarding the measurements that the
        occluder was already dragging; in [0, 30], default 8; 0 disables it.
    history_frames : int
        Clean measurements kept for that restart (a least-squares line through them
        gives the coasting velocity), in [2, 100]; default 16. Increasing it steadies
        the velocity and makes it slower to reflect turns.
    size_change_occludes : bool
        A CamShift area grown past ``max_area_growth`` is an occlusion whatever the colour
        match (the paper; default True: an occluder of the target's own colour makes
        CamShift spread with a strong match). False measures such a target's position at its
        last size instead.
    max_missing_frames : int
        Beyond the paper: frames in a row without a measurement (partial or severe) after
        which the target is lost, >= 1; default 100. A prediction that leaves the frame is
        lost at once.
    sampling_noise : bool
        Beyond the paper: Tb and ``reacquire_distance`` are widened, for each target, by the
        distance that sampling noise alone puts between two of its colour histograms
        (:func:`pipeline.stages.camshift.sampling_distance` on its first box), added in
        quadrature; default True. The paper's Tb suits a target of some thousand pixels,
        whose noise is about 0.1 and barely moves it; a person 6 x 13 px wide has a noise of
        about 0.4, and with the paper's Tb its every frame would count as occluded. False: the
        thresholds as given.
    """

    section = "occlusion"

    distance_threshold: float = param(0.4, gt=0, le=1)
    max_area_growth: float = param(2.0, gt=1)
    min_area_fraction: float = param(0.4, gt=0, le=1)
    reference_frames: int = param(20, ge=1)
    max_severe_frames: int = param(50, ge=1)
    search_scale: float = param(1.5, ge=1, le=5)
    missing_search_scale: float = param(3.0, ge=1, le=10)
    reacquire_distance: float = param(0.3, gt=0, le=1)
    rewind_frames: int = param(8, ge=0, le=30)
    history_frames: int = param(16, ge=2, le=100)
    size_change_occludes: bool = True
    max_missing_frames: int = param(100, ge=1)
    sampling_noise: bool = True

    def check(self) -> None:
        if not self.reacquire_distance <= self.distance_threshold:
            raise ValueError(
                "occlusion.reacquire_distance must be in (0, distance_threshold]; got "
                f"{self.reacquire_distance!r}"
            )


class Grade(enum.StrEnum):
    NONE = "none"
    PARTIAL = "partial"
    SEVERE = "severe"


def grade_occlusion(
    d: float,
    area_px2: float,
    min_area_px2: float | None,
    cfg: OcclusionConfig,
    predicted_area_px2: float | None = None,
) -> Grade:
    """The paper's grading of one frame (``min_area_px2`` None: no reference yet, never severe by
    area; ``predicted_area_px2`` None: no size-change test)."""
    grown = predicted_area_px2 is not None and area_px2 > cfg.max_area_growth * predicted_area_px2
    if d < cfg.distance_threshold and not (grown and cfg.size_change_occludes):
        return Grade.NONE
    if min_area_px2 is not None and area_px2 < min_area_px2:
        return Grade.SEVERE
    if area_px2 <= 0:
        return Grade.SEVERE
    return Grade.PARTIAL


@dataclass(frozen=True)
class AreaReference:
    """Areas of the first unoccluded frames and the min_area they imply."""

    areas: tuple[float, ...] = ()

    def add(self, area_px2: float, cfg: OcclusionConfig) -> AreaReference:
        if len(self.areas) >= cfg.reference_frames:
            return self
        return AreaReference((*self.areas, float(area_px2)))

    def min_area(self, cfg: OcclusionConfig) -> float | None:
        return cfg.min_area_fraction * min(self.areas) if self.areas else None


def next_severe_run(grade: Grade, run: int) -> int:
    """Consecutive severe frames after this one."""
    return run + 1 if grade == Grade.SEVERE else 0


def is_lost(severe_run: int, cfg: OcclusionConfig) -> bool:
    """More than K0 consecutive severe frames."""
    return severe_run > cfg.max_severe_frames


def nearer_overlapping(boxes: tuple[BBox, ...], i: int) -> tuple[BBox, ...]:
    """The boxes that overlap ``boxes[i]`` and reach lower in the frame: where targets stand on
    one ground seen from above it (street and surveillance views), the nearer ones, which hide
    ``boxes[i]`` where they overlap it. Boxes whose bottoms are level hide nothing of each
    other; seen from straight above (nadir aerial footage) the order means nothing.

    Examples
    --------
    >>> far, near = BBox(10, 10, 10, 30), BBox(15, 20, 10, 30)
    >>> nearer_overlapping((far, near), 0)
    (BBox(x=15, y=20, w=10, h=30),)
    >>> nearer_overlapping((far, near), 1), nearer_overlapping((far, BBox(20, 20, 5, 5)), 0)
    ((), ())
    """
    b = boxes[i]
    return tuple(
        o
        for j, o in enumerate(boxes)
        if j != i and o.x < b.x2 and b.x < o.x2 and o.y < b.y2 and b.y < o.y2 and o.y2 > b.y2
    )
