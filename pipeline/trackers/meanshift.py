"""``meanshift``: kernel-weighted HSV-histogram mean shift with the +-10 % scale search.

The method the dual-channel paper compares against (Comaniciu et al. with Comaniciu's
scale adaptation), and the visible-only mode of the dual tracker. On an infrared-only
sequence it runs on an intensity histogram of the IR frame. The model is the histogram of
the first frame (no update), as in the classic method.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.io.sequence import FramePair
from pipeline.stages.histogram import appearance_bins, kernel_histogram, search_roi
from pipeline.stages.meanshift import mean_shift_scale_search
from pipeline.tracker_config import MeanShiftTrackerConfig
from pipeline.trackers.base import pick_channel
from pipeline.trackers.lifecycle import transition
from pipeline.types import (
    BBox,
    FrameResult,
    InitTarget,
    TargetResult,
    TargetStatus,
)


@dataclass(frozen=True)
class MeanShiftTarget:
    """Per-target state: current box, model histogram and status."""

    id: int
    box: BBox
    q: np.ndarray
    status: TargetStatus


@dataclass(frozen=True)
class MeanShiftState:
    targets: tuple[MeanShiftTarget, ...]
    channel: str


@dataclass(frozen=True)
class MeanShift:
    """The ``meanshift`` tracker: one pure core over its ``meanshift`` section.

    Parameters
    ----------
    cfg : MeanShiftTrackerConfig
        The histogram binning (``histogram``) and the mean shift with its scale search
        (``search``).

    Examples
    --------
    >>> import numpy as np
    >>> from pipeline.io.sequence import FramePair
    >>> from pipeline.types import BBox, InitTarget
    >>> def frame(i, x):
    ...     vis = np.full((60, 80, 3), 90, np.uint8)
    ...     vis[20:40, x:x + 10] = (30, 30, 200)
    ...     return FramePair(i, vis, None)
    >>> ms = MeanShift(MeanShiftTrackerConfig())
    >>> state, _ = ms.init(frame(1, 30), [InitTarget(1, BBox(30, 20, 10, 20))])
    >>> state, result = ms.step(state, frame(2, 33))
    >>> abs(result.targets[0].box.cx - 38) < 1.5  # the square moved from x = 35 to 38
    True
    """

    cfg: MeanShiftTrackerConfig

    def init(
        self, frames: FramePair, targets: Sequence[InitTarget]
    ) -> tuple[MeanShiftState, FrameResult]:
        """The colour model of every target from its box in the first frame."""
        channel = pick_channel(frames, "visible")
        image = getattr(frames, channel)
        bins, m = appearance_bins(image, self.cfg.histogram)
        states, results = [], []
        for t in targets:
            q = kernel_histogram(bins, t.box, m)
            states.append(MeanShiftTarget(t.id, t.box, q, TargetStatus.TRACKING))
            results.append(TargetResult(t.id, t.box, TargetStatus.TRACKING, "init", rho=1.0))
        return MeanShiftState(tuple(states), channel), FrameResult(frames.index, tuple(results))

    def track_target(
        self, image: np.ndarray, target: MeanShiftTarget
    ) -> tuple[MeanShiftTarget, TargetResult]:
        """One frame of mean shift + scale search for one target."""
        mcfg = self.cfg.search
        h, w = image.shape[:2]
        box = target.box
        x0, y0, x1, y1 = search_roi(box, mcfg.search_margin, w, h)
        bins, _ = appearance_bins(np.ascontiguousarray(image[y0:y1, x0:x1]), self.cfg.histogram)
        res = mean_shift_scale_search(
            bins, target.q, (box.cx - x0, box.cy - y0), (box.w / 2, box.h / 2), mcfg
        )
        best = res.best
        if best.no_support:
            status = TargetStatus.OCCLUDED_SEVERE
            new_box = box
        else:
            status = TargetStatus.TRACKING
            f = mcfg.scale_rate * res.best_factor + (1.0 - mcfg.scale_rate)
            new_box = BBox.from_center(
                best.center[0] + x0, best.center[1] + y0, box.w * f, box.h * f
            )
        new_t = dataclasses.replace(target, box=new_box, status=status)
        tracking = status == TargetStatus.TRACKING
        result = TargetResult(
            target.id,
            new_box,
            status,
            "meanshift",
            iterations={"meanshift": res.iterations},
            rho=best.rho,
            confidence=float(np.clip(best.rho, 0.0, 1.0)) if tracking else 0.2,
            diagnostics={"scale_factor": res.best_factor, "mass_fraction": best.mass_fraction},
        )
        return new_t, result

    def step(self, state: MeanShiftState, frames: FramePair) -> tuple[MeanShiftState, FrameResult]:
        """One frame for every target; a target whose window holds none of its colours is
        occluded (and visible again once it does)."""
        t0 = time.perf_counter()
        image = getattr(frames, state.channel)
        new_targets, results, events = [], [], []
        for t in state.targets:
            nt, r = self.track_target(image, t)
            if nt.status != t.status:
                why = "no model colour in the window" if nt.status.is_occluded else "colour found"
                events += transition(t.id, t.status, nt.status, why)
            new_targets.append(nt)
            results.append(r)
        dt = time.perf_counter() - t0
        return (
            dataclasses.replace(state, targets=tuple(new_targets)),
            FrameResult(frames.index, tuple(results), tuple(events), {"meanshift": dt}),
        )
