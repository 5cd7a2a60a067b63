"""The dual tracker's contour cue: the DRLSE level set in the IR frame (the paper's step 3) and
the checks that make a contour a measurement."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from pipeline.stages.contour import (
    ContourConfig,
    ContourReason,
    ContourResult,
    LevelSetMemory,
    extract_contour,
    size_reason,
)
from pipeline.stages.levelset import LevelSetConfig
from pipeline.trackers.dual.state import DualTarget
from pipeline.types import BBox


@dataclass(frozen=True)
class ContourCue:
    """The IR contour of a target (or of a merged group), started where the other cues put it.

    Parameters
    ----------
    cfg : ContourConfig
        ``dual.contour``: region, starts, failure tests, and whether the tracker applies them.
    levelset : LevelSetConfig
        ``dual.levelset``: the DRLSE evolution.
    """

    cfg: ContourConfig
    levelset: LevelSetConfig

    def first(self, ir: np.ndarray, box: BBox) -> ContourResult:
        """The contour of a target given at ``box`` on its first frame (a cold start)."""
        return extract_contour(ir, box, self.cfg, self.levelset)

    def part(
        self, box: BBox, c: ContourResult | None, entering: tuple[bool, bool]
    ) -> tuple[float, float] | None:
        """The warm part of a target given at ``box`` that its first contour ``c`` shows
        (``warm_part``): the part's width and height as shares of the box's; None where the
        contour did not collapse, has too little contrast, reaches out of the box or covers
        under ``warm_part_min_fraction`` of it, and for a target walking in (its contour is
        cut, not a part).

        Examples
        --------
        >>> cue = ContourCue(ContourConfig(), LevelSetConfig())
        >>> rider = ContourResult(False, ContourReason.COLLAPSE, BBox(12, 0, 12, 18), (), 50,
        ...                       20.0, LevelSetMemory.empty())
        >>> cue.part(BBox(0, 0, 36, 36), rider, (False, False))
        (0.3333333333333333, 0.5)
        """
        cfg = self.cfg
        if not cfg.warm_part or c is None or c.box is None or any(entering):
            return None
        if c.reason != ContourReason.COLLAPSE:
            return None
        k = c.box
        if abs(c.contrast) < cfg.min_contrast or k.area < cfg.warm_part_min_fraction * box.area:
            return None
        if k.intersect(box).area < 0.9 * k.area:
            return None
        return (k.w / box.w, k.h / box.h)

    def start(
        self,
        filter_box: BBox | None,
        meanshift: tuple[float, float],
        prediction: tuple[float, float],
        colour_good: bool,
    ) -> tuple[float, float]:
        """Where the level set starts: the filter's detection when it is confident
        (``filter_box``, else None), the mean shift when its colour match is good (or always,
        with ``start_at = "meanshift"``), else the prediction."""
        if filter_box is not None:
            return filter_box.center
        if colour_good or self.cfg.start_at == "meanshift":
            return meanshift
        return prediction

    def extract(
        self,
        ir: np.ndarray,
        t: DualTarget,
        start: tuple[float, float],
        cold: bool = False,
    ) -> ContourResult:
        """The contour of ``t`` around ``start`` at its current size, warm-started from its last
        good level set moved by its displacement (unless ``cold``). For a target whose IR
        shows a part of it (:attr:`DualTarget.part`), a contour that collapsed to that part's
        size (the size tests against the part at the target's current size) is marked
        ``part``: the target is all there, and its box is not measured from the part."""
        w, h = t.size
        expected = BBox.from_center(start[0], start[1], w, h)
        memory = None if cold else t.memory
        shift = (start[0] - t.memory_center[0], start[1] - t.memory_center[1])
        c = extract_contour(ir, expected, self.cfg, self.levelset, memory, shift)
        if t.part is None or c.box is None or c.reason != ContourReason.COLLAPSE:
            return c
        fw, fh = t.part
        part = BBox.from_center(c.box.cx, c.box.cy, fw * w, fh * h)
        if size_reason(c.box, part, self.cfg) != ContourReason.OK:
            return c
        return dataclasses.replace(c, part=True)

    def due(self, t: DualTarget, frame: int, confident: bool) -> bool:
        """Whether ``t``'s level set runs at ``frame``: always, unless it has no level set to
        warm-start from, its last ``n`` cold starts found nothing, ``n`` over
        ``retry_after_empty``, the filter detects it ``confident``-ly, and fewer than ``2 ** (n
        - retry_after_empty)`` frames (at most ``retry_empty_frames``) have passed since the
        last (``ContourConfig``)."""
        over = t.empty_starts - self.cfg.retry_after_empty
        if over <= 0 or not confident or t.missing > 0:
            return True
        if t.memory is not None and t.memory.warm:
            return True
        wait = min(2 ** min(over, 30), self.cfg.retry_empty_frames)
        return frame - t.empty_start_frame >= wait

    @staticmethod
    def not_run() -> ContourResult:
        """The result of a frame whose level set did not run (:meth:`due`)."""
        return ContourResult(
            False, ContourReason.NOT_RUN, None, (), 0, 0.0, LevelSetMemory.empty()
        )

    @staticmethod
    def empty_starts(t: DualTarget, c: ContourResult | None, frame: int) -> tuple[int, int]:
        """``t``'s (``empty_starts``, ``empty_start_frame``) after this frame's contour ``c``:
        one more after a cold start that found nothing, none after one that found something,
        unchanged without a level set run."""
        if c is None or c.reason == ContourReason.NOT_RUN or c.warm:
            return t.empty_starts, t.empty_start_frame
        if c.reason == ContourReason.NO_COMPONENT:
            return t.empty_starts + 1, frame
        return 0, -1

    def group(
        self,
        ir: np.ndarray,
        box: BBox,
        memory: LevelSetMemory | None,
        shift: tuple[float, float],
        cold_scale: float,
        max_ratio: float,
        part_width: float,
    ) -> ContourResult:
        """One contour over a merged group's ``box`` (the union of its members), whose area and
        sides may reach ``max_ratio`` times the box's (it holds several targets)."""
        cfg = dataclasses.replace(
            self.cfg, max_area_ratio=max_ratio, max_dimension_ratio=max_ratio
        )
        return extract_contour(
            ir,
            box,
            cfg,
            self.levelset,
            memory,
            shift,
            cold_init=box.scaled(cold_scale),
            part_width=part_width,
        )

    def usable(self, c: ContourResult | None) -> bool:
        """A contour with a box that the tracker may measure with: one that passed the failure
        tests, or any without ``checks``, or one that failed only for low contrast with
        ``trust_faded``."""
        return (
            c is not None
            and c.box is not None
            and (
                c.ok
                or not self.cfg.checks
                or (self.cfg.trust_faded and c.reason == ContourReason.LOW_CONTRAST)
            )
        )

    def contrasted(self, c: ContourResult | None, factor: float = 1.0) -> bool:
        """The contour's contrast reaches ``factor`` times ``min_contrast``."""
        return c is not None and abs(c.contrast) >= factor * self.cfg.min_contrast
