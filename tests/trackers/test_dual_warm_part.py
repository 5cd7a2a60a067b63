"""The warm part of a target (``contour.warm_part``): a first contour that collapsed to a part of
the given box with contrast is what the IR shows of the target, and a later contour of that
part's size is ``part``, not a partial occlusion."""

from __future__ import annotations

import dataclasses

import numpy as np

from pipeline.stages import kalman
from pipeline.stages.contour import ContourConfig, ContourReason
from pipeline.stages.levelset import LevelSetConfig
from pipeline.trackers.dual.contour import ContourCue
from pipeline.trackers.dual.state import DualTarget
from pipeline.types import BBox, TargetStatus

BOX = BBox(40.0, 30.0, 36.0, 36.0)


def _ir(part: tuple[int, int, int, int] | None) -> np.ndarray:
    """A 120 x 160 IR frame at 80, a warm (200) rectangle ``(x, y, w, h)`` in it."""
    ir = np.full((120, 160), 80, np.uint8)
    if part is not None:
        x, y, w, h = part
        ir[y : y + h, x : x + w] = 200
    return ir


def _target(part, memory=None) -> DualTarget:
    return DualTarget(
        1,
        BOX,
        (BOX.w, BOX.h),
        np.ones(4) / 4,
        TargetStatus.TRACKING,
        kalman.init_state(BOX, kalman.KalmanConfig()),
        memory=memory,
        memory_center=BOX.center,
        part=part,
    )


def test_a_collapsed_first_contour_is_taken_as_the_targets_warm_part():
    cue = ContourCue(ContourConfig(), LevelSetConfig())
    rider = (52, 30, 12, 18)  # the upper middle of the box
    c = cue.first(_ir(rider), BOX)
    assert c.reason == ContourReason.COLLAPSE
    part = cue.part(BOX, c, (False, False))
    assert part is not None
    fw, fh = part
    # planted: a third of the box's width, half its height (12 x 18 px)
    assert abs(fw * BOX.w - 12.0) <= 1.5 and abs(fh * BOX.h - 18.0) <= 1.5, part
    # the same part a frame later, 3 px on: a collapse of the part's size, marked ``part``
    moved = cue.extract(_ir((55, 30, 12, 18)), _target(part, c.memory), (61.0, 48.0))
    assert moved.reason == ContourReason.COLLAPSE and moved.part
    # a part a quarter of its first size is no longer it: a partial occlusion
    small = cue.extract(_ir((55, 30, 6, 9)), _target(part), (61.0, 48.0), cold=True)
    assert small.reason == ContourReason.COLLAPSE and not small.part
    # a target without a part: every collapse is one
    plain = cue.extract(_ir((55, 30, 12, 18)), _target(None), (61.0, 48.0), cold=True)
    assert plain.reason == ContourReason.COLLAPSE and not plain.part


def test_no_part_without_contrast_inside_the_box_or_when_off():
    cue = ContourCue(ContourConfig(), LevelSetConfig())
    c = cue.first(_ir((52, 30, 12, 18)), BOX)
    assert cue.part(BOX, c, (True, False)) is None  # walking in: the contour is cut, not a part
    faint = dataclasses.replace(c, contrast=2.0)
    assert cue.part(BOX, faint, (False, False)) is None
    outside = dataclasses.replace(c, box=c.box.shifted(30.0, 0.0))
    assert cue.part(BOX, outside, (False, False)) is None
    tiny = dataclasses.replace(c, box=BBox(56.0, 34.0, 4.0, 6.0))
    assert cue.part(BOX, tiny, (False, False)) is None
    off = ContourCue(ContourConfig(warm_part=False), LevelSetConfig())
    assert off.part(BOX, c, (False, False)) is None
