"""The dual tracker's re-detector: where the filter looks for a hidden or lost target."""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass

from pipeline.io.sequence import FramePair
from pipeline.stages import detection
from pipeline.tracker_config import RedetectConfig
from pipeline.trackers.dual.colour import ColourStep
from pipeline.trackers.dual.state import BackgroundSource, DualTarget, History
from pipeline.types import BBox


def region_candidates(
    center: tuple[float, float],
    radius: float,
    size: tuple[float, float],
    W: int,
    H: int,
    limit: int,
    turn: int,
) -> list[tuple[float, float]]:
    """Up to ``limit`` centres on a grid of one target size (per axis) within ``radius`` of
    ``center``, inside the frame: the nearest first; a larger grid is covered over successive
    calls (``turn``).

    Examples
    --------
    >>> region_candidates((50.0, 50.0), 25.0, (20.0, 20.0), 100, 100, limit=4, turn=0)
    [(50.0, 30.0), (30.0, 50.0), (70.0, 50.0), (50.0, 70.0)]
    """
    sx, sy = max(size[0], 4.0), max(size[1], 4.0)
    nx, ny = int(radius // sx), int(radius // sy)
    pts = [
        (center[0] + ix * sx, center[1] + iy * sy)
        for iy in range(-ny, ny + 1)
        for ix in range(-nx, nx + 1)
        if (ix or iy) and math.hypot(ix * sx, iy * sy) <= radius + 1e-9
    ]
    pts = [p for p in pts if 0 <= p[0] < W and 0 <= p[1] < H]
    pts.sort(key=lambda p: math.hypot(p[0] - center[0], p[1] - center[1]))
    if len(pts) <= limit:
        return pts
    k = turn % -(-len(pts) // limit)
    return pts[k * limit : (k + 1) * limit]


def recent_speed(t: DualTarget) -> float:
    """The target's speed over its recent clean measurements, px per frame (0 with fewer than
    two)."""
    if len(t.history) < 2:
        return 0.0
    a, b = t.history[0], t.history[-1]
    return math.hypot(b[1] - a[1], b[2] - a[2]) / max(b[0] - a[0], 1.0)


def step_speed(history: History, steps: int = 4) -> float | None:
    """The mean distance between consecutive clean measurements ``(frame, cx, cy, w, h)`` over
    the last ``steps`` of them, px per frame (None with fewer than two): how far a target moves
    in a frame, whichever way (a target walking to and fro has a small :func:`recent_speed` and
    a large step speed).

    Examples
    --------
    >>> step_speed(((1, 10.0, 0, 5, 5), (2, 20.0, 0, 5, 5), (4, 0.0, 0, 5, 5)))
    10.0
    >>> step_speed(((1, 10.0, 0, 5, 5),)) is None
    True
    """
    h = history[-(steps + 1) :]
    if len(h) < 2:
        return None
    path = sum(math.hypot(b[1] - a[1], b[2] - a[2]) for a, b in itertools.pairwise(h))
    return path / max(h[-1][0] - h[0][0], 1.0)


@dataclass(frozen=True)
class Redetector:
    """The places a missing target is looked for this frame, by its filter.

    Parameters
    ----------
    cfg : RedetectConfig
        ``dual.redetect``: how the search region widens, how often it runs, and the detector
        of the whole-frame search.
    """

    cfg: RedetectConfig

    @functools.cached_property
    def detection(self) -> detection.DetectionConfig:
        """The detector settings of the whole-frame search (IR regions only)."""
        return detection.infrared_only(self.cfg.detection)

    def candidates(
        self,
        frames: FramePair,
        cs: ColourStep,
        size: tuple[float, float],
        background: BackgroundSource = None,
        occupied: tuple[BBox, ...] = (),
    ) -> list[tuple[float, float]]:
        """Centres to try for the missing target of ``cs``: the mean shift's, and every
        ``every_frames`` frames a region widening with the missing frames around the prediction
        (and around where the target was last seen; with ``regions_in_radius``, the detector's
        regions within it first) or, after ``global_after_frames``, the detector's regions of
        the whole frame. A region whose centre lies inside one of the ``occupied`` boxes (the
        other targets' this frame) is not tried, within the radius or over the whole frame: a
        target's look-alike that another target holds is that target."""
        t, cfg = cs.t, self.cfg
        cands = []
        if cs.informative and not math.isnan(cs.rho1):
            cands.append(cs.y1)
        if t.missing % cfg.every_frames:
            return cands
        if t.missing >= cfg.global_after_frames:
            return cands + self.frame_candidates(frames, size, background, occupied)
        centres, radius = self._region(cs, size)
        grid = self._around(frames, cs, size, centres, radius)
        if not cfg.regions_in_radius:
            return cands + grid
        near = self._regions_near(frames, size, background, centres, radius, occupied)
        return cands + near + grid[: max(cfg.candidates - len(near), 0)]

    def _regions_near(
        self,
        frames: FramePair,
        size: tuple[float, float],
        background: BackgroundSource,
        centres: list[tuple[float, float]],
        radius: float,
        occupied: tuple[BBox, ...],
    ) -> list[tuple[float, float]]:
        """The centres of the detector's regions of the target's size (:meth:`_sized`) within
        ``radius`` of one of ``centres`` and inside none of the ``occupied`` boxes, the closest
        in size first, at most ``candidates``."""
        near = [
            c
            for c in self._sized(frames, size, background)
            if any(math.hypot(c[0] - o[0], c[1] - o[1]) <= radius for o in centres)
            and not _inside_any(c, occupied)
        ]
        return near[: self.cfg.candidates]

    def _region(
        self, cs: ColourStep, size: tuple[float, float]
    ) -> tuple[list[tuple[float, float]], float]:
        """The widening region: its centres (the prediction, and the last clean measurement
        where that lies over half the target's smaller side away) and its radius, px, widening
        at the target's speed or, where that is not known yet, ``unknown_speed_px_per_frame``."""
        t, cfg = cs.t, self.cfg
        speed = max(recent_speed(t), t.speed) if cfg.last_seen else 0.0
        rate = max(cfg.radius_px_per_frame, speed)
        if len(t.history) < 2 and t.speed == 0.0:
            rate = max(rate, cfg.unknown_speed_px_per_frame)
        radius = 0.5 * math.hypot(*size) + rate * t.missing
        centres = [cs.y0]
        seen = self.last_seen(t)
        if seen is not None and math.hypot(seen[0] - cs.y0[0], seen[1] - cs.y0[1]) > 0.5 * min(
            size
        ):
            centres.append(seen)
        return centres, radius

    def _around(
        self,
        frames: FramePair,
        cs: ColourStep,
        size: tuple[float, float],
        centres: list[tuple[float, float]],
        radius: float,
    ) -> list[tuple[float, float]]:
        """The widening region's grid of candidates, shared between its centres (a target that
        turned or stopped while hidden is near where it was last seen, not ahead)."""
        t, cfg = cs.t, self.cfg
        H, W = frames.shape
        turn = t.missing // cfg.every_frames
        per = -(-cfg.candidates // len(centres))
        out: list[tuple[float, float]] = []
        for c0 in centres:
            out += region_candidates(c0, radius, size, W, H, per, turn)
        return out

    def last_seen(self, t: DualTarget) -> tuple[float, float] | None:
        """Centre of the target's last clean measurement, where the widened search also looks
        (None without one or with ``last_seen`` off)."""
        if not self.cfg.last_seen or not t.history:
            return None
        return (t.history[-1][1], t.history[-1][2])

    def frame_candidates(
        self,
        frames: FramePair,
        size: tuple[float, float],
        background: BackgroundSource = None,
        occupied: tuple[BBox, ...] = (),
    ) -> list[tuple[float, float]]:
        """Centres of the detector's regions in the IR frame (the visible one without IR) of
        ``min_region_area_ratio`` to four times the target's area and inside none of the
        ``occupied`` boxes, the closest in size first, at most ``candidates``: where a lost
        target may be anywhere. ``background`` is the detector's (the sequence's, or a function
        returning it, read only here)."""
        free = [c for c in self._sized(frames, size, background) if not _inside_any(c, occupied)]
        return free[: self.cfg.candidates]

    def _sized(
        self, frames: FramePair, size: tuple[float, float], background: BackgroundSource
    ) -> list[tuple[float, float]]:
        """The centres of all the frame's regions of ``min_region_area_ratio`` to four times the
        target's area, the closest in size first."""
        area = max(size[0] * size[1], 1.0)
        lo = self.cfg.min_region_area_ratio
        near = [r for r in self._regions(frames, background) if lo <= r.box.area / area <= 4.0]
        near.sort(key=lambda r: abs(math.log(max(r.box.area, 1.0) / area)))
        return [r.box.center for r in near]

    def _regions(
        self, frames: FramePair, background: BackgroundSource
    ) -> tuple[detection.Region, ...]:
        """The detector's regions of this frame, detected once however many missing targets
        search it (the last frame's are kept, with the image and background they came from)."""
        img = frames.infrared if frames.infrared is not None else frames.visible
        assert img is not None
        bg = background() if callable(background) else background
        last = self.__dict__.get("_last")
        if last is not None and last[0] is img and last[1] is bg:
            return last[2]
        found = detection.detect(img, self.detection, bg).regions
        self.__dict__["_last"] = (img, bg, found)  # a cache beside the frozen fields
        return found


def _inside_any(c: tuple[float, float], boxes: tuple[BBox, ...]) -> bool:
    """Whether the point ``c`` lies inside (or on the edge of) one of ``boxes``."""
    return any(b.contains(c[0], c[1]) for b in boxes)
