"""One target, one frame: cues, the decision, the updates, the events and the reported result."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from pipeline.config import PipelineConfig
from pipeline.io.sequence import FramePair
from pipeline.stages import appearance as app
from pipeline.stages.contour import ContourReason, ContourResult, extract_contour
from pipeline.stages.extent import colour_extent, search_window
from pipeline.tracker_config import DualConfig
from pipeline.trackers.dual.cues import (
    AppearanceCue,
    ColourStep,
    add_time,
    appearance_cue,
    filter_images,
    match_at,
)
from pipeline.trackers.dual.decide import Case, Decision, Evidence, decide
from pipeline.trackers.dual.update import (
    fused_size,
    motion_update,
    update_appearance,
    update_colour_model,
)
from pipeline.types import BBox, Event, EventKind, TargetResult, TargetStatus

CONFIDENCE = {
    TargetStatus.TRACKING: 1.0,
    TargetStatus.OCCLUDED_PARTIAL: 0.6,
    TargetStatus.OCCLUDED_SEVERE: 0.3,
}


def outside(box: BBox, shape: tuple[int, ...]) -> bool:
    """Less than a quarter of the box lies inside the frame."""
    return box.clip(shape[1], shape[0]).area < 0.25 * box.area


def walked_in_size(
    size: tuple[float, float],
    c: ContourResult | None,
    rho_c: float,
    entering: tuple[bool, bool],
    dcfg: DualConfig,
) -> tuple[float, float] | None:
    """The size of a target first given cut by the frame's border, once it has walked in: its first
    clean contour (no longer at the border, its colour not contradicting it) is larger than the
    given box by more than ``scale_agree_ratio`` along a cut axis. None otherwise (also when the
    target was not cut after all)."""
    if (
        c is None
        or c.box is None
        or not c.ok
        or (not math.isnan(rho_c) and rho_c < dcfg.colour_min_rho)
    ):
        return None
    grown = [
        entering[k] and (c.box.w, c.box.h)[k] > dcfg.scale_agree_ratio * size[k] for k in (0, 1)
    ]
    if not any(grown):
        return None
    return (c.box.w if grown[0] else size[0], c.box.h if grown[1] else size[1])


def measured_extent(
    cs: ColourStep, decision: Decision, cfg: PipelineConfig, neighbours: tuple[BBox, ...] = ()
) -> BBox | None:
    """The target's colour extent (frame px) around the measured position at its current size, when
    the colour is informative, the decision let the models learn (a hidden target's colours are
    someone else's) and no other target (``neighbours``, their boxes this frame) lies within the
    extent's window."""
    if not (
        decision.measured
        and decision.learn
        and cs.informative
        and cs.bins is not None
        and decision.box is not None
    ):
        return None
    here = BBox.from_center(decision.box.cx, decision.box.cy, cs.t.size[0], cs.t.size[1])
    win = search_window(here, cfg.extent)
    if any(win.iou(b) > 0 for b in neighbours):
        return None
    x0, y0 = cs.roi0
    around = BBox(here.x - x0, here.y - y0, here.w, here.h)
    e = colour_extent(cs.bins, cs.t.q, around, cfg.extent)
    return None if e is None else BBox(e.x + x0, e.y + y0, e.w, e.h)


def contour_start(cs: ColourStep, cue, dcfg: DualConfig) -> tuple[float, float]:
    """Where the level set starts: the filter's detection when it is confident, the mean shift when
    its colour match is good (or the paper's way, without the channel weighting or the motion
    prior), else the prediction."""
    if cue is not None and cue.psr >= dcfg.psr_confident:
        return cue.box.center
    if (cs.informative and cs.rho1 >= dcfg.occlusion_rho) or not (
        dcfg.channel_weighting and dcfg.motion_prior
    ):
        return cs.y1
    return cs.y0


@dataclass(frozen=True)
class Measured:
    """One target's cues and decision in one frame, before anything is updated
    (:func:`measure_single`)."""

    cs: ColourStep
    cue: AppearanceCue | None
    contour: ContourResult | None
    rho_contour: float
    rho_appearance: float
    evidence: Evidence
    decision: Decision
    start: tuple[float, float] | None = None


def measure_single(
    frames: FramePair,
    cs: ColourStep,
    cfg: PipelineConfig,
    mode: str,
    timing: dict[str, float],
    start: tuple[float, float] | None = None,
    background=None,
) -> Measured:
    """The cues of one target that is not merged (filter, IR contour, colour at each) and the
    decision over them.

    ``start`` forces a cold contour start there (a blob after a split); ``background`` is the
    detector's, for the whole-frame search of a missing target
    (:func:`pipeline.trackers.dual.cues.frame_candidates`)."""
    dcfg: DualConfig = cfg.dual
    t, prior = cs.t, cs.prior
    ir = frames.infrared if mode in ("dual", "ir") else None
    H, W = frames.shape
    cue = appearance_cue(frames, cs, cfg, mode, timing, frames.index, background)
    clock = time.perf_counter()

    # the IR contour, started where the other cues put the target
    c: ContourResult | None = None
    if ir is not None:
        yc, memory = (
            (start, None) if start is not None else (contour_start(cs, cue, dcfg), t.memory)
        )
        expected = BBox.from_center(yc[0], yc[1], t.size[0], t.size[1])
        shift = (yc[0] - t.memory_center[0], yc[1] - t.memory_center[1])
        c = extract_contour(ir, expected, cfg.contour, cfg.levelset, memory, shift)
        add_time(timing, "levelset", clock)
    contour_usable = (
        c is not None
        and c.box is not None
        and (
            c.ok
            or not dcfg.contour_checks
            or (not dcfg.channel_weighting and c.reason == ContourReason.LOW_CONTRAST)
        )
    )
    mmf = cfg.meanshift.min_mass_fraction
    rho_c = (
        match_at(cs.bins, t.q, c.box, cs.roi0, mmf)
        if (
            contour_usable
            and cs.informative
            and cs.bins is not None
            and c is not None
            and c.box is not None
        )
        else float("nan")
    )

    rho_a = (
        match_at(cs.bins, t.q, cue.box, cs.roi0, mmf)
        if (cue is not None and cs.informative and cs.bins is not None)
        else float("nan")
    )
    ref = t.reference_size
    ev = Evidence(
        measured_last=t.missing == 0 or start is not None,
        missing=t.missing,
        prior=BBox.from_center(float(prior.x[0]), float(prior.x[1]), ref[0], ref[1]),
        ref_size=ref,
        colour_informative=(cs.informative and mode != "ir")
        or (mode == "ir" and not math.isnan(cs.rho1)),
        rho_meanshift=cs.rho1,
        meanshift_box=cs.box1 if not math.isnan(cs.rho1) else None,
        contour_box=c.box if contour_usable and c is not None else None,
        contour_ok=bool(c is not None and c.ok),
        contour_reason=c.reason if c is not None else "no-contour",
        rho_contour=rho_c,
        appearance_box=cue.box if cue is not None else None,
        psr=cue.psr if cue is not None else float("nan"),
        rho_appearance=rho_a,
        last=t.box,
        support=cue.support if cue is not None else (math.nan, math.nan),
        redetected=bool(cue is not None and cue.redetected),
        outside=outside(prior.box, (H, W)),
        prior_std_px=(math.sqrt(float(prior.P[0, 0])), math.sqrt(float(prior.P[1, 1]))),
    )
    decision: Decision = decide(ev, dcfg)
    if start is not None and not decision.measured and c is not None and c.box is not None:
        # the blob a split re-associated this target with is its measurement
        decision = Decision(
            Case.CONTOUR, c.box, 1.0, TargetStatus.TRACKING, "split-blob", True, False, "levelset"
        )
    return Measured(cs, cue, c, rho_c, rho_a, ev, decision, start)


def finish_single(
    frames: FramePair,
    cs: ColourStep,
    cfg: PipelineConfig,
    mode: str,
    timing: dict[str, float],
    start: tuple[float, float] | None = None,
    events_in: list[Event] | None = None,
    neighbours: tuple[BBox, ...] = (),
    background=None,
):
    """:func:`measure_single` and :func:`update_single` of one target that is not merged: (new
    state, result, events)."""
    m = measure_single(frames, cs, cfg, mode, timing, start, background)
    return update_single(frames, m, cfg, mode, timing, events_in, neighbours)


def update_single(
    frames: FramePair,
    m: Measured,
    cfg: PipelineConfig,
    mode: str,
    timing: dict[str, float],
    events_in: list[Event] | None = None,
    neighbours: tuple[BBox, ...] = (),
):
    """Size, models, motion, events and the reported result of one target after its decision: (new
    state, result, events). ``neighbours`` are the other targets' boxes this frame (the colour
    extent is not measured where one is near)."""
    dcfg: DualConfig = cfg.dual
    cs, cue, c, decision, start = m.cs, m.cue, m.contour, m.decision, m.start
    rho_c, rho_a = m.rho_contour, m.rho_appearance
    t, prior = cs.t, cs.prior
    ref = t.reference_size
    clock = time.perf_counter()

    # size, output box, models
    extent = measured_extent(cs, decision, cfg, neighbours) if dcfg.extent_cue else None
    size, app_size = fused_size(
        t.size,
        t.app_size,
        decision,
        c,
        cue,
        dcfg,
        cfg.contour.min_contrast,
        extent,
        cfg.extent.max_ratio if dcfg.extent_cue else 1.0,
    )
    entering = t.entering
    walked_in = walked_in_size(size, c, rho_c, entering, dcfg) if any(entering) else None
    if walked_in is not None:  # its first clean contour shows what the frame's border hid
        size, decision = (
            walked_in,
            Decision(
                Case.CONTOUR,
                c.box,
                1.0,
                TargetStatus.TRACKING,
                "walked-in",  # type: ignore[union-attr]
                False,
                False,
                "levelset",
            ),
        )
    if any(entering) and c is not None and c.ok:
        entering = (False, False)
    if decision.measured:
        assert decision.box is not None
        out = BBox.from_center(decision.box.cx, decision.box.cy, size[0], size[1])
        missing_n = 0
    else:
        out = BBox.from_center(float(prior.x[0]), float(prior.x[1]), ref[0], ref[1])
        missing_n = t.missing + 1
    q, colour_decision, rho2 = update_colour_model(
        t.q, cs.bins, cs.roi0, out, decision.learn, decision.measured, cfg
    )
    vis, irf = filter_images(frames, mode)
    model = t.appearance
    if walked_in is not None:  # the filter learns the whole target afresh
        app_size = size
        if model is not None:
            model = app.train(vis, irf, out, cfg.appearance)
    else:
        model = update_appearance(
            model,
            vis,
            irf,
            BBox.from_center(out.cx, out.cy, *app_size),
            decision,
            colour_decision,
            cs.informative,
            cfg.appearance,
            frames.index,
        )
    events: list[Event] = list(events_in or [])
    if (
        not colour_decision.update
        and t.last_update.startswith("updated")
        and colour_decision.reason != "colour-uninformative"
    ):
        events.append(
            Event(
                EventKind.MODEL_FROZEN, f"T{t.id} model frozen ({colour_decision.reason})", (t.id,)
            )
        )
    clock = add_time(timing, "model_update", clock)
    kf, history, out = motion_update(cs, decision, out, frames.index, dcfg, cfg.kalman, t.history)
    add_time(timing, "kalman", clock)

    status = decision.status
    if status != t.status:
        if status == TargetStatus.LOST:
            events.append(
                Event(EventKind.LOST, f"T{t.id} lost ({decision.why.replace('-', ' ')})", (t.id,))
            )
        elif t.status == TargetStatus.LOST:
            events.append(
                Event(EventKind.REACQUIRED, f"T{t.id} re-acquired ({decision.why})", (t.id,))
            )
        elif status.is_occluded and not t.status.is_occluded:
            events.append(
                Event(
                    EventKind.OCCLUSION_START,
                    f"T{t.id} {status} ({decision.why}, contour "
                    f"{c.reason if c is not None else 'none'})",
                    (t.id,),
                )
            )
        elif not status.is_occluded and t.status.is_occluded:
            events.append(
                Event(EventKind.OCCLUSION_END, f"T{t.id} visible again ({decision.why})", (t.id,))
            )

    good_contour = decision.case == Case.CONTOUR and c is not None and c.box is not None
    nt = dataclasses.replace(
        t,
        box=out,
        size=size,
        app_size=app_size,
        entering=entering,
        q=q,
        status=status,
        kf=kf,
        memory=c.memory if good_contour and c is not None else t.memory,
        memory_center=c.box.center
        if good_contour and c is not None and c.box is not None
        else t.memory_center,
        history=history,
        missing=missing_n,
        last_update=str(colour_decision),
        split_frame=frames.index if start is not None else t.split_frame,
        appearance=model,
        case=decision.case.value,
    )
    diag = {
        "rho_y1": cs.rho1,
        "rho_y2": rho2,
        "rho_contour": rho_c,
        "contrast": c.contrast if c is not None else math.nan,
        "bright_fraction": cs.bright,
        "missing": float(missing_n),
        "components": float(len(c.components)) if c else 0.0,
        "psr": cue.psr if cue is not None else math.nan,
        "scale_factor": cue.scale_factor if cue is not None else math.nan,
        "psr_visible": cue.support[0] if cue is not None else math.nan,
        "psr_ir": cue.support[1] if cue is not None else math.nan,
        "rho_appearance": rho_a,
    }
    overlays = {"prediction": prior.box, "meanshift": cs.box1}
    if cue is not None:
        overlays["appearance"] = cue.box
    res = TargetResult(
        t.id,
        out,
        status,
        decision.stage,
        {"meanshift": cs.ms_iters, "levelset": c.iterations if c else 0},
        rho2 if not np.isnan(rho2) else cs.rho1,
        f"{colour_decision}" + ("" if c is None or c.ok else f";contour-{c.reason}"),
        CONFIDENCE.get(status, 0.0),
        c.contour if c is not None and c.box is not None else (),
        diag,
        overlays,
        decision=f"{decision.case.value}:{decision.why}",
    )
    return nt, res, events
