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

from pipeline.config import PipelineConfig
from pipeline.io.sequence import FramePair
from pipeline.stages.histogram import appearance_bins, kernel_histogram, search_roi
from pipeline.stages.meanshift import mean_shift_scale_search
from pipeline.trackers.base import pick_channel
from pipeline.types import (
    BBox,
    Event,
    EventKind,
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


def track_target(
    image: np.ndarray, target: MeanShiftTarget, cfg: PipelineConfig
) -> tuple[MeanShiftTarget, TargetResult]:
    """One frame of mean shift + scale search for one target (``cfg`` is a PipelineConfig)."""
    hcfg, mcfg = cfg.histogram, cfg.meanshift
    h, w = image.shape[:2]
    box = target.box
    x0, y0, x1, y1 = search_roi(box, mcfg.search_margin, w, h)
    bins, _m = appearance_bins(np.ascontiguousarray(image[y0:y1, x0:x1]), hcfg)
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
        new_box = BBox.from_center(best.center[0] + x0, best.center[1] + y0, box.w * f, box.h * f)
    new_t = dataclasses.replace(target, box=new_box, status=status)
    result = TargetResult(
        target.id,
        new_box,
        status,
        "meanshift",
        iterations={"meanshift": res.iterations},
        rho=best.rho,
        confidence=float(np.clip(best.rho, 0.0, 1.0)) if status == TargetStatus.TRACKING else 0.2,
        diagnostics={"scale_factor": res.best_factor, "mass_fraction": best.mass_fraction},
    )
    return new_t, result


def init(
    frames: FramePair, targets: Sequence[InitTarget], cfg: PipelineConfig
) -> tuple[MeanShiftState, FrameResult]:
    channel = pick_channel(frames, "visible")
    image = getattr(frames, channel)
    bins, m = appearance_bins(image, cfg.histogram)
    states, results = [], []
    for t in targets:
        q = kernel_histogram(bins, t.box, m)
        states.append(MeanShiftTarget(t.id, t.box, q, TargetStatus.TRACKING))
        results.append(TargetResult(t.id, t.box, TargetStatus.TRACKING, "init", rho=1.0))
    return MeanShiftState(tuple(states), channel), FrameResult(frames.index, tuple(results))


def step(
    state: MeanShiftState, frames: FramePair, cfg: PipelineConfig
) -> tuple[MeanShiftState, FrameResult]:
    t0 = time.perf_counter()
    image = getattr(frames, state.channel)
    new_targets, results, events = [], [], []
    for t in state.targets:
        nt, r = track_target(image, t, cfg)
        if nt.status != t.status:
            kind = EventKind.OCCLUSION_START if nt.status.is_occluded else EventKind.OCCLUSION_END
            events.append(
                Event(
                    kind,
                    f"T{t.id} {nt.status} (no model colour in the window)"
                    if nt.status.is_occluded
                    else f"T{t.id} {nt.status}",
                    (t.id,),
                )
            )
        new_targets.append(nt)
        results.append(r)
    dt = time.perf_counter() - t0
    return (
        dataclasses.replace(state, targets=tuple(new_targets)),
        FrameResult(frames.index, tuple(results), tuple(events), {"meanshift": dt}),
    )
