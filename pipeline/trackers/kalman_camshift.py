"""``kalman-camshift``: CamShift searching from a Kalman prediction, with graded occlusion.

The tracker of Yan et al. 2014 (docs/algorithms.md §7):

1. predict the box with the 12-state constant-acceleration Kalman filter;
2. run CamShift on the hue (visible) or intensity (IR) back-projection from a search
   window centred on the prediction (enlarged, with the last good size, while the
   target is missing);
3. grade occlusion from the Bhattacharyya distance d of the CamShift region to the
   model and its area (``pipeline.stages.occlusion``):
   not occluded -> the CamShift box is the measurement and the output;
   partial -> the prediction is the output and is fed back as the measurement;
   severe -> predicted position with the last good size, fed back likewise;
   more than K0 severe frames -> lost (reported; the filter coasts and the search goes on);
4. a missing target whose d falls below Tb again is re-acquired.

Readings of the paper where it is open (documented choices):

* ``lastrect``: the box recorded during partial occlusion is the box output for that
  frame (the prediction), not the CamShift window, which during an occlusion often
  covers the occluder.
* The "colour histogram" compared by d is a kernel-weighted hue x saturation histogram
  (16 x 4, the same low-saturation/low-brightness mask as the back-projection;
  intensity in IR), while
  CamShift back-projects the hue histogram as the paper says: hue alone cannot tell a
  brown wall from a red shirt, and the mask keeps the model and the CamShift region
  comparable although they cover different parts of the target.
* The paper's "fixed-size search window and fixed target size" while the target is
  severely occluded is ``cv2.meanShift`` (fixed window) from the prediction with the
  last good size; it is the re-acquisition check whenever the target is missing, since
  CamShift's adaptive window grows onto same-coloured occluders.

Beyond the paper:

* while the target is occluded the size rates and the accelerations are held at zero,
  so the filter coasts at constant velocity and size: fed its own prediction back (as
  the paper prescribes), the 12-state filter otherwise keeps whatever acceleration and
  growth the last, occluder-dragged CamShift measurements suggested;
* when an occlusion starts the motion estimate restarts from a straight line through
  the recent clean measurements (``occlusion.rewind_frames``/``history_frames``,
  ``pipeline.stages.motion``), discarding those dragged measurements and the
  measurement jitter the filter's velocity carries;
* a missing target is taken back only when d < ``occlusion.reacquire_distance`` (0.3),
  a hysteresis below Tb;
* with ``occlusion.size_change_occludes`` off, a strong colour match is not an occlusion
  even when the CamShift area grew: its position is measured, with the last size;
* the back-projected model is weighted against the target's surround on the first frame
  (``camshift.background_weighting_scale``, the corrected background-weighted histogram of
  Ning et al. 2012), so that colours the target shares with the ground barely pull CamShift's
  window off it;
* the size measured is the last good box's, scaled by CamShift's area within
  ``camshift.max_scale_step`` a frame with its aspect ratio kept (:func:`scaled_like`):
  CamShift's moments shrink the window onto the target's best-matching part;
* Tb and the re-acquisition distance are widened by the target's own sampling noise
  (``occlusion.sampling_noise``): a small target's histogram is noisy;
* coasting is bounded: a prediction that leaves the frame, or ``occlusion.max_missing_frames``
  frames without a measurement, end in ``lost``, where the motion stops.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.config import PipelineConfig
from pipeline.io.sequence import FramePair
from pipeline.stages import kalman
from pipeline.stages.camshift import (
    back_project,
    background_weights,
    box_mask,
    camshift,
    feature,
    histogram,
    kernel_masked_histogram,
    sampling_distance,
    to_hsv,
    weighted_model,
)
from pipeline.stages.histogram import bhattacharyya, bhattacharyya_distance
from pipeline.stages.motion import coast_start, hold_rates, stop
from pipeline.stages.occlusion import (
    AreaReference,
    Grade,
    OcclusionConfig,
    grade_occlusion,
    is_lost,
    next_severe_run,
)
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
class KCTarget:
    """Per-target state."""

    id: int
    kf: kalman.GaussianState
    model: np.ndarray  # hue / intensity histogram for the back-projection
    colour: np.ndarray  # masked hue x saturation (or IR intensity) histogram for d
    status: TargetStatus
    last_rect: BBox
    reference: AreaReference
    severe_run: int = 0
    history: tuple[
        tuple[float, float, float, float, float], ...
    ] = ()  # clean (frame, cx, cy, w, h), newest last
    missing_run: int = 0  # frames in a row without a measurement
    # the colour distance sampling noise alone gives this target (camshift.sampling_distance)
    noise_d: float = 0.0


@dataclass(frozen=True)
class KCState:
    targets: tuple[KCTarget, ...]
    channel: str


def _bins(cfg: PipelineConfig, channel: str) -> int:
    c = cfg.camshift
    return c.hue_bins if channel == "visible" else c.intensity_bins


SATURATION_BINS = 4


def _feature(
    image: np.ndarray,
    cfg: PipelineConfig,
    channel: str,
    saturation_bins: int = 1,
    hsv: np.ndarray | None = None,
):
    c = cfg.camshift
    return feature(image, _bins(cfg, channel), c.min_saturation, c.min_value, saturation_bins, hsv)


def init(
    frames: FramePair, targets: Sequence[InitTarget], cfg: PipelineConfig
) -> tuple[KCState, FrameResult]:
    channel = pick_channel(frames, cfg.opencv.channel)
    image = getattr(frames, channel)
    f = _feature(image, cfg, channel, cfg.camshift.saturation_bins)
    fc = _feature(image, cfg, channel, SATURATION_BINS)
    states, results = [], []
    for t in targets:
        mask = box_mask(image.shape, t.box)
        q = histogram(f, mask)
        if cfg.camshift.background_weighting_scale > 0:  # beyond the paper: CBWH
            q = weighted_model(
                q, background_weights(f, t.box, cfg.camshift.background_weighting_scale)
            )
        colour = kernel_masked_histogram(fc, t.box)
        kf = kalman.init_state(t.box, cfg.kalman)
        noise = sampling_distance(fc, t.box) if cfg.occlusion.sampling_noise else 0.0
        states.append(
            KCTarget(
                t.id,
                kf,
                q,
                colour,
                TargetStatus.TRACKING,
                t.box,
                AreaReference((t.box.area,)),
                noise_d=noise,
            )
        )
        results.append(TargetResult(t.id, t.box, TargetStatus.TRACKING, "init", rho=1.0))
    return KCState(tuple(states), channel), FrameResult(frames.index, tuple(results))


def _clip_center(box: BBox, width: int, height: int) -> BBox:
    """Move a box so that at least half of it lies inside the frame."""
    cx = min(max(box.cx, 0.0), float(width))
    cy = min(max(box.cy, 0.0), float(height))
    return box.with_center(cx, cy)


def _fixed_size_candidates(
    prob: np.ndarray,
    center: tuple[float, float],
    size: BBox,
    scale: float,
    cfg_cs: object,
    last_seen: tuple[float, float] | None = None,
) -> list[BBox]:
    """The paper's search during severe occlusion: a fixed-size window (``cv2.meanShift``), from
    the prediction with the target's last good size, and once more after a first pass with the
    window enlarged ``scale`` times (to reach a target that re-appears away from its prediction);
    and from ``last_seen``, where the target was last measured cleanly, when given (a target that
    stopped behind the occluder while its prediction coasted on)."""
    h, w = prob.shape
    crit = (
        cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT,
        cfg_cs.max_iterations,
        cfg_cs.epsilon_px,
    )
    out = []
    starts = [center]
    if last_seen is not None and 0 <= last_seen[0] < w and 0 <= last_seen[1] < h:
        starts.append(last_seen)
    big = BBox.from_center(center[0], center[1], size.w * scale, size.h * scale)
    _, win = cv2.meanShift(prob, _clip_center(big, w, h).to_cv(w, h), crit)
    starts.append((win[0] + win[2] / 2, win[1] + win[3] / 2))
    for cx, cy in starts:
        small = BBox.from_center(cx, cy, size.w, size.h)
        _, win = cv2.meanShift(prob, _clip_center(small, w, h).to_cv(w, h), crit)
        out.append(BBox.from_center(win[0] + win[2] / 2, win[1] + win[3] / 2, size.w, size.h))
    return out


@functools.lru_cache(maxsize=256)
def _noise_aware(ocfg: OcclusionConfig, noise_d: float) -> OcclusionConfig:
    """The occlusion thresholds Tb and the re-acquisition distance widened by the target's
    sampling noise, added in quadrature."""
    return dataclasses.replace(
        ocfg,
        distance_threshold=min(math.hypot(ocfg.distance_threshold, noise_d), 1.0),
        reacquire_distance=min(math.hypot(ocfg.reacquire_distance, noise_d), 1.0),
    )


def scaled_like(found: BBox, last: BBox, max_step: float) -> BBox:
    """``last`` moved to ``found``'s centre and scaled by the square root of their areas' ratio,
    the scale held within ``1 +- max_step`` (``camshift.max_scale_step``)."""
    s = (found.area / max(last.area, 1e-9)) ** 0.5
    s = min(max(s, 1.0 - max_step), 1.0 + max_step)
    return BBox.from_center(found.cx, found.cy, last.w * s, last.h * s)


def _search_window(prior_box: BBox, scale: float, width: int, height: int) -> BBox:
    return _clip_center(prior_box.scaled(scale), width, height).clip(width, height)


def _match(fc, box: BBox, colour: np.ndarray) -> float:
    """Bhattacharyya distance between the colour model and the masked histogram inside ``box``."""
    return bhattacharyya_distance(bhattacharyya(kernel_masked_histogram(fc, box), colour))


def track_target(
    image: np.ndarray, t: KCTarget, cfg: PipelineConfig, channel: str, frame: int
) -> tuple[KCTarget, TargetResult, list[Event]]:
    """One frame of Kalman-CAMShift for one target."""
    kcfg, ocfg, ccfg = cfg.kalman, cfg.occlusion, cfg.camshift
    if t.noise_d > 0:
        ocfg = _noise_aware(ocfg, t.noise_d)
    F, Q = kalman.motion_model(kcfg)
    H, R = kalman.measurement_model(kcfg)
    h, w = image.shape[:2]
    missing = t.status != TargetStatus.TRACKING
    prior = kalman.predict(hold_rates(t.kf, kcfg) if missing else t.kf, F, Q)
    pbox = prior.box
    window = _search_window(
        pbox, ocfg.missing_search_scale if missing else ocfg.search_scale, w, h
    )
    margin = 12 + 0.25 * max(
        window.w, window.h
    )  # CamShift grows the window by 10 px for its moments
    x0, y0 = int(max(window.x - margin, 0)), int(max(window.y - margin, 0))
    x1, y1 = int(min(window.x2 + margin, w)), int(min(window.y2 + margin, h))
    roi = np.ascontiguousarray(image[y0:y1, x0:x1])
    hsv = to_hsv(roi) if roi.ndim == 3 else None
    f = _feature(roi, cfg, channel, ccfg.saturation_bins, hsv)
    fc = (
        f
        if ccfg.saturation_bins == SATURATION_BINS
        else _feature(roi, cfg, channel, SATURATION_BINS, hsv)
    )
    prob = back_project(f, t.model)
    local = window.shifted(-x0, -y0)
    cs = camshift(prob, local, ccfg.max_iterations, ccfg.epsilon_px)
    found = cs.box.shifted(x0, y0) if cs.box is not None else None
    d = _match(fc, cs.box, t.colour) if cs.box is not None else 1.0
    area = cs.area_px2
    source = "camshift"
    if missing and d >= ocfg.reacquire_distance:
        # re-acquisition check with the fixed size the paper prescribes while the target is missing
        seen = (t.history[-1][1] - x0, t.history[-1][2] - y0) if t.history else None
        for fixed in _fixed_size_candidates(
            prob, (pbox.cx - x0, pbox.cy - y0), t.last_rect, ocfg.missing_search_scale, ccfg, seen
        ):
            d_fixed = _match(fc, fixed, t.colour)
            if d_fixed < d:
                found, d, area, source = (
                    fixed.shifted(x0, y0),
                    d_fixed,
                    fixed.area,
                    "meanshift-fixed",
                )
    min_area = t.reference.min_area(ocfg)
    grade = grade_occlusion(d, area, min_area, ocfg, (t.last_rect if missing else pbox).area)
    if missing and grade == Grade.NONE and d >= ocfg.reacquire_distance:
        grade = (
            Grade.PARTIAL if area >= (min_area or 0.0) else Grade.SEVERE
        )  # hysteresis: not yet taken back
    events: list[Event] = []
    reference = t.reference
    severe_run = next_severe_run(grade, t.severe_run)
    grown = (
        found is not None and area > ocfg.max_area_growth * (t.last_rect if missing else pbox).area
    )
    # CamShift spread onto its colour around: no size
    if grade == Grade.NONE and found is not None and grown:
        found = BBox.from_center(found.cx, found.cy, t.last_rect.w, t.last_rect.h)
        source = "camshift-position"
    outside = pbox.clip(w, h).area < 0.25 * pbox.area
    if (
        grade == Grade.NONE
        and source == "camshift"
        and found is not None
        and ccfg.max_scale_step < 1
    ):
        found = scaled_like(found, t.last_rect, ccfg.max_scale_step)
    if grade == Grade.NONE and found is not None:
        kf = kalman.correct(prior, kalman.box_measurement(found), H, R, kcfg).state
        out, status, last_rect = found, TargetStatus.TRACKING, found
        if not missing:
            reference = reference.add(area, ocfg)
        if t.status == TargetStatus.LOST:
            events.append(Event(EventKind.REACQUIRED, f"T{t.id} re-acquired (d={d:.2f})", (t.id,)))
        elif missing:
            events.append(
                Event(EventKind.OCCLUSION_END, f"T{t.id} visible again (d={d:.2f})", (t.id,))
            )
    elif t.status == TargetStatus.LOST:  # keep coasting and searching; nothing is measured
        kf, status, source, last_rect = prior, TargetStatus.LOST, "kalman", t.last_rect
        out = BBox.from_center(pbox.cx, pbox.cy, t.last_rect.w, t.last_rect.h)
    elif grade == Grade.PARTIAL:
        kf = kalman.correct(prior, kalman.box_measurement(pbox), H, R, kcfg).state
        out, status, source, last_rect = pbox, TargetStatus.OCCLUDED_PARTIAL, "kalman", pbox
    else:
        sized = BBox.from_center(pbox.cx, pbox.cy, t.last_rect.w, t.last_rect.h)
        kf = kalman.correct(prior, kalman.box_measurement(sized), H, R, kcfg).state
        out, status, source, last_rect = sized, TargetStatus.OCCLUDED_SEVERE, "kalman", t.last_rect
        if is_lost(severe_run, ocfg):
            status, kf = TargetStatus.LOST, prior
            events.append(
                Event(EventKind.LOST, f"T{t.id} lost after {severe_run} severe frames", (t.id,))
            )
    missing_run = 0 if status == TargetStatus.TRACKING else t.missing_run + 1
    if status.is_occluded and (outside or missing_run > ocfg.max_missing_frames):
        why = (
            "its prediction left the frame"
            if outside
            else f"{missing_run} frames without a measurement"
        )
        status, kf, source = TargetStatus.LOST, stop(prior), "kalman"
        out = BBox.from_center(kf.box.cx, kf.box.cy, t.last_rect.w, t.last_rect.h)
        events.append(Event(EventKind.LOST, f"T{t.id} lost ({why})", (t.id,)))
    elif status == TargetStatus.LOST and outside:
        kf = stop(kf)  # a lost target does not coast on out of the frame
    history = t.history
    if status == TargetStatus.TRACKING and d < 0.5 * ocfg.distance_threshold and found is not None:
        history = (*t.history, (float(frame), found.cx, found.cy, found.w, found.h))[
            -ocfg.history_frames :
        ]
    if status.is_occluded and not missing:
        events.append(
            Event(
                EventKind.OCCLUSION_START,
                f"T{t.id} {status} (d={d:.2f}, area={area:.0f})",
                (t.id,),
            )
        )
        restart = coast_start(t.history, prior, frame, ocfg.rewind_frames)
        if restart is not None:  # discard the measurements the occluder was dragging
            kf = restart
            out = (
                kf.box
                if status == TargetStatus.OCCLUDED_PARTIAL
                else BBox.from_center(kf.box.cx, kf.box.cy, t.last_rect.w, t.last_rect.h)
            )
            last_rect = out if status == TargetStatus.OCCLUDED_PARTIAL else t.last_rect
            source = "kalman-refit"
    elif status == TargetStatus.OCCLUDED_SEVERE and t.status == TargetStatus.OCCLUDED_PARTIAL:
        events.append(
            Event(
                EventKind.OCCLUSION_START,
                f"T{t.id} occlusion now severe (area={area:.0f})",
                (t.id,),
            )
        )
    if status == TargetStatus.TRACKING:
        severe_run = 0
    conf = {
        TargetStatus.TRACKING: 1.0 - d,
        TargetStatus.OCCLUDED_PARTIAL: 0.5,
        TargetStatus.OCCLUDED_SEVERE: 0.25,
    }.get(status, 0.0)
    diag = {
        "d": d,
        "area_px2": area,
        "min_area_px2": min_area if min_area is not None else float("nan"),
        "severe_run": float(severe_run),
    }
    overlays = {"prediction": pbox, "search": window}
    if found is not None:
        overlays["camshift"] = found
    new_t = dataclasses.replace(
        t,
        kf=kf,
        status=status,
        last_rect=last_rect,
        reference=reference,
        severe_run=severe_run,
        history=history,
        missing_run=missing_run,
    )
    res = TargetResult(
        t.id,
        out,
        status,
        source,
        {},
        1.0 - d * d,
        "frozen:paper-fixed-model",
        max(conf, 0.0),
        (),
        diag,
        overlays,
    )
    return new_t, res, events


def step(state: KCState, frames: FramePair, cfg: PipelineConfig) -> tuple[KCState, FrameResult]:
    t0 = time.perf_counter()
    image = getattr(frames, state.channel)
    new, results, events = [], [], []
    for t in state.targets:
        nt, r, ev = track_target(image, t, cfg, state.channel, frames.index)
        new.append(nt)
        results.append(r)
        events += ev
    return (
        dataclasses.replace(state, targets=tuple(new)),
        FrameResult(
            frames.index,
            tuple(results),
            tuple(events),
            {"kalman_camshift": time.perf_counter() - t0},
        ),
    )
