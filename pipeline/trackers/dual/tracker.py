"""The dual tracker's frame loop: every target's cues, the merge test, and the group or single
finish."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence

from pipeline.config import PipelineConfig
from pipeline.io.sequence import FramePair
from pipeline.stages import appearance as app
from pipeline.stages import kalman
from pipeline.stages.contour import extract_contour
from pipeline.stages.detection import Background
from pipeline.stages.histogram import appearance_bins, kernel_histogram
from pipeline.stages.merge import merge_groups
from pipeline.tracker_config import DualConfig
from pipeline.trackers.dual.cues import colour_image, colour_stage, filter_images
from pipeline.trackers.dual.group import finish_group
from pipeline.trackers.dual.single import finish_single
from pipeline.trackers.dual.state import DualState, DualTarget
from pipeline.types import Event, EventKind, FrameResult, InitTarget, TargetResult, TargetStatus


def mode_of(frames: FramePair) -> str:
    """``dual`` with both channels, else ``ir`` or ``visible``: the cues follow the channels
    present."""
    if frames.visible is not None and frames.infrared is not None:
        return "dual"
    return "ir" if frames.infrared is not None else "visible"


def init(
    frames: FramePair,
    targets: Sequence[InitTarget],
    cfg: PipelineConfig,
    background: Background | Callable[[], Background | None] | None = None,
) -> tuple[DualState, FrameResult]:
    """Start on the first frame: the colour histogram, the correlation filter and the level set of
    every target; ``background`` is the detector's for this frame (:attr:`DualState.background`).
    """
    dcfg: DualConfig = cfg.dual
    mode = mode_of(frames)
    bins, m = appearance_bins(colour_image(frames, mode), cfg.histogram)
    vis, ir = filter_images(frames, mode)
    states, results = [], []
    H, W = frames.shape
    for t in targets:
        b = t.box
        q = kernel_histogram(bins, t.box, m)
        kf = kalman.init_state(t.box, cfg.kalman)
        c = extract_contour(ir, t.box, cfg.contour, cfg.levelset) if ir is not None else None
        # walking in: the given box and the target's IR blob are both cut by the frame's border
        cut = c.at_border if c is not None and c.box is not None else (False, False)
        entering = (
            cut[0] and (b.x <= 1.0 or b.x2 >= W - 1.0),
            cut[1] and (b.y <= 1.0 or b.y2 >= H - 1.0),
        )
        model = app.train(vis, ir, t.box, cfg.appearance) if dcfg.appearance_cue else None
        states.append(
            DualTarget(
                t.id,
                t.box,
                (t.box.w, t.box.h),
                q,
                TargetStatus.TRACKING,
                kf,
                c.memory if c is not None and c.box is not None else None,
                t.box.center,
                ((1.0, t.box.cx, t.box.cy, t.box.w, t.box.h),),
                appearance=model,
                app_size=(t.box.w, t.box.h),
                entering=entering,
            )
        )
        results.append(
            TargetResult(
                t.id,
                t.box,
                TargetStatus.TRACKING,
                "init",
                {"levelset": c.iterations if c is not None else 0},
                1.0,
                "none:init",
                1.0,
                c.contour if c is not None else (),
                decision="init:given",
            )
        )
    return DualState(tuple(states), mode, background=background), FrameResult(
        frames.index, tuple(results)
    )


def step(
    state: DualState, frames: FramePair, cfg: PipelineConfig
) -> tuple[DualState, FrameResult]:
    """One frame: mean shift for every target, the merge test (eq. 10), then each group and each
    single target."""
    t0 = time.perf_counter()
    timing: dict[str, float] = {}
    dcfg: DualConfig = cfg.dual
    steps = {t.id: colour_stage(frames, t, cfg, state.mode, timing) for t in state.targets}
    # eq. 10 on the mean-shift positions; a member of a merge is tested at its prediction instead,
    # since its mean shift may sit on whoever hides it (a look-alike, above all) and would hold the
    # group together
    live = {
        i: cs.box_prior if cs.t.status == TargetStatus.MERGED else cs.box1
        for i, cs in steps.items()
        if cs.t.status != TargetStatus.LOST
    }
    held = {
        i for i, cs in steps.items() if frames.index - cs.t.split_frame <= dcfg.split_hold_frames
    }
    merging = dcfg.merge_handling and state.mode != "visible" and len(live) > 1
    groups = merge_groups(live, held, dcfg.remerge_scale) if merging else []
    in_group = {i for g in groups for i in g}
    done: dict[int, tuple[DualTarget, TargetResult, list[Event]]] = {}
    new_groups = []
    for g in groups:
        out, mem = finish_group(
            frames, [steps[i] for i in g], cfg, state.mode, timing, state.groups
        )
        done.update(out)
        if mem is not None:
            new_groups.append(mem)
    for i, cs in steps.items():
        if i in in_group:
            continue
        ev: list[Event] = []
        start = None
        if cs.t.status == TargetStatus.MERGED:  # its group dissolved without a visible split
            ev.append(Event(EventKind.SPLIT, f"T{i} separated (merge test no longer holds)", (i,)))
            start = cs.box_prior.center
        others = tuple(b for j, b in live.items() if j != i)
        done[i] = finish_single(
            frames,
            cs,
            cfg,
            state.mode,
            timing,
            start=start,
            events_in=ev,
            neighbours=others,
            background=state.background,
        )
    new, results, events = [], [], []
    for t in state.targets:
        nt, r, ev = done[t.id]
        new.append(nt)
        results.append(r)
        events += ev
    timing["dual"] = time.perf_counter() - t0
    return (
        dataclasses.replace(state, targets=tuple(new), groups=tuple(new_groups)),
        FrameResult(frames.index, tuple(results), tuple(events), timing),
    )
