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
from pipeline.tracker_config import CamShiftConfig, KalmanCamShiftConfig
from pipeline.trackers.base import pick_channel
from pipeline.trackers.lifecycle import coast_ends, left_frame, transition
from pipeline.types import (
    BBox,
    Event,
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
    # clean (frame, cx, cy, w, h), newest last
    history: tuple[tuple[float, float, float, float, float], ...] = ()
    missing_run: int = 0  # frames in a row without a measurement
    # the colour distance sampling noise alone gives this target (camshift.sampling_distance)
    noise_d: float = 0.0


@dataclass(frozen=True)
class KCState:
    targets: tuple[KCTarget, ...]
    channel: str


SATURATION_BINS = 4
"""Saturation bins of the masked hue x saturation histogram the occlusion test compares."""


@dataclass(frozen=True)
class _Found:
    """What CamShift (or the fixed-size re-acquisition search) found in one frame."""

    window: BBox  # the search window (frame px)
    box: BBox | None
    d: float  # Bhattacharyya distance of the colour there to the model
    area: float
    source: str


@dataclass(frozen=True)
class _Outcome:
    """One target's frame after the occlusion grade: its state's parts, its output and events."""

    kf: kalman.GaussianState
    out: BBox
    status: TargetStatus
    source: str
    last_rect: BBox
    events: tuple[Event, ...] = ()


@dataclass(frozen=True)
class KalmanCamShift:
    """The ``kalman-camshift`` tracker: one pure core over its ``kalman_camshift`` section.

    Parameters
    ----------
    cfg : KalmanCamShiftConfig
        Its channel, the CamShift search (``camshift``), the motion model (``kalman``) and the
        occlusion grading (``occlusion``).
    """

    cfg: KalmanCamShiftConfig

    def _feature(
        self,
        image: np.ndarray,
        channel: str,
        saturation_bins: int = 1,
        hsv: np.ndarray | None = None,
    ):
        c = self.cfg.camshift
        bins = c.hue_bins if channel == "visible" else c.intensity_bins
        return feature(image, bins, c.min_saturation, c.min_value, saturation_bins, hsv)

    def init(
        self, frames: FramePair, targets: Sequence[InitTarget]
    ) -> tuple[KCState, FrameResult]:
        """Every target's back-projected model (weighted against its surround), colour model,
        sampling noise and Kalman state on the first frame."""
        ccfg = self.cfg.camshift
        channel = pick_channel(frames, self.cfg.channel)
        image = getattr(frames, channel)
        f = self._feature(image, channel, ccfg.saturation_bins)
        fc = self._feature(image, channel, SATURATION_BINS)
        states, results = [], []
        for t in targets:
            q = histogram(f, box_mask(image.shape, t.box))
            if ccfg.background_weighting_scale > 0:  # beyond the paper: CBWH
                q = weighted_model(
                    q, background_weights(f, t.box, ccfg.background_weighting_scale)
                )
            noise = sampling_distance(fc, t.box) if self.cfg.occlusion.sampling_noise else 0.0
            states.append(
                KCTarget(
                    t.id,
                    kalman.init_state(t.box, self.cfg.kalman),
                    q,
                    kernel_masked_histogram(fc, t.box),
                    TargetStatus.TRACKING,
                    t.box,
                    AreaReference((t.box.area,)),
                    noise_d=noise,
                )
            )
            results.append(TargetResult(t.id, t.box, TargetStatus.TRACKING, "init", rho=1.0))
        return KCState(tuple(states), channel), FrameResult(frames.index, tuple(results))

    def step(self, state: KCState, frames: FramePair) -> tuple[KCState, FrameResult]:
        """One frame for every target."""
        t0 = time.perf_counter()
        image = getattr(frames, state.channel)
        new, results, events = [], [], []
        for t in state.targets:
            nt, r, ev = self.track_target(image, t, state.channel, frames.index)
            new.append(nt)
            results.append(r)
            events += ev
        timing = {"kalman_camshift": time.perf_counter() - t0}
        return (
            dataclasses.replace(state, targets=tuple(new)),
            FrameResult(frames.index, tuple(results), tuple(events), timing),
        )

    def _search(
        self,
        image: np.ndarray,
        t: KCTarget,
        pbox: BBox,
        ocfg: OcclusionConfig,
        channel: str,
    ) -> _Found:
        """CamShift from the prediction (in a window enlarged while the target is missing); a
        missing target not found within the re-acquisition distance is also looked for with the
        fixed size the paper prescribes."""
        ccfg = self.cfg.camshift
        missing = t.status != TargetStatus.TRACKING
        h, w = image.shape[:2]
        scale = ocfg.missing_search_scale if missing else ocfg.search_scale
        window = _search_window(pbox, scale, w, h)
        # CamShift grows the window by 10 px for its moments
        margin = 12 + 0.25 * max(window.w, window.h)
        x0, y0 = int(max(window.x - margin, 0)), int(max(window.y - margin, 0))
        x1, y1 = int(min(window.x2 + margin, w)), int(min(window.y2 + margin, h))
        roi = np.ascontiguousarray(image[y0:y1, x0:x1])
        hsv = to_hsv(roi) if roi.ndim == 3 else None
        f = self._feature(roi, channel, ccfg.saturation_bins, hsv)
        fc = f
        if ccfg.saturation_bins != SATURATION_BINS:
            fc = self._feature(roi, channel, SATURATION_BINS, hsv)
        prob = back_project(f, t.model)
        cs = camshift(prob, window.shifted(-x0, -y0), ccfg.max_iterations, ccfg.epsilon_px)
        found = cs.box.shifted(x0, y0) if cs.box is not None else None
        d = _match(fc, cs.box, t.colour) if cs.box is not None else 1.0
        area, source = cs.area_px2, "camshift"
        if missing and d >= ocfg.reacquire_distance:
            seen = (t.history[-1][1] - x0, t.history[-1][2] - y0) if t.history else None
            for fixed in _fixed_size_candidates(
                prob,
                (pbox.cx - x0, pbox.cy - y0),
                t.last_rect,
                ocfg.missing_search_scale,
                ccfg,
                seen,
            ):
                d_fixed = _match(fc, fixed, t.colour)
                if d_fixed < d:
                    found, d, area, source = (
                        fixed.shifted(x0, y0),
                        d_fixed,
                        fixed.area,
                        "meanshift-fixed",
                    )
        return _Found(window, found, d, area, source)

    def _measured(self, s: _Found, grade: Grade, t: KCTarget, ref_area: float) -> _Found:
        """The box a clear CamShift result measures: at its position with the last size when
        CamShift spread onto the colours around (no size), else the last box scaled by
        CamShift's area within ``max_scale_step``."""
        if grade != Grade.NONE or s.box is None:
            return s
        found, source = s.box, s.source
        if s.area > self.cfg.occlusion.max_area_growth * ref_area:
            found = BBox.from_center(found.cx, found.cy, t.last_rect.w, t.last_rect.h)
            source = "camshift-position"
        step = self.cfg.camshift.max_scale_step
        if source == "camshift" and step < 1:
            found = scaled_like(found, t.last_rect, step)
        return dataclasses.replace(s, box=found, source=source)

    def _outcome(
        self,
        grade: Grade,
        s: _Found,
        t: KCTarget,
        prior: kalman.GaussianState,
        severe_run: int,
        ocfg: OcclusionConfig,
    ) -> _Outcome:
        """The paper's step 3: a clear match is measured; a partial occlusion outputs and feeds
        back the prediction; a severe one the predicted position with the last good size, lost
        after K0 such frames; a lost target coasts on."""
        H, R = kalman.measurement_model(self.cfg.kalman)
        pbox, last, d = prior.box, t.last_rect, s.d

        def fed(box: BBox) -> kalman.GaussianState:
            return kalman.correct(prior, kalman.box_measurement(box), H, R, self.cfg.kalman).state

        if grade == Grade.NONE and s.box is not None:
            ev = transition(t.id, t.status, TargetStatus.TRACKING, f"d={d:.2f}")
            return _Outcome(fed(s.box), s.box, TargetStatus.TRACKING, s.source, s.box, ev)
        if t.status == TargetStatus.LOST:  # keep coasting and searching; nothing is measured
            out = BBox.from_center(pbox.cx, pbox.cy, last.w, last.h)
            return _Outcome(prior, out, TargetStatus.LOST, "kalman", last)
        if grade == Grade.PARTIAL:
            return _Outcome(fed(pbox), pbox, TargetStatus.OCCLUDED_PARTIAL, "kalman", pbox)
        sized = BBox.from_center(pbox.cx, pbox.cy, last.w, last.h)
        if is_lost(severe_run, ocfg):
            ev = transition(t.id, t.status, TargetStatus.LOST, f"after {severe_run} severe frames")
            return _Outcome(prior, sized, TargetStatus.LOST, "kalman", last, ev)
        return _Outcome(fed(sized), sized, TargetStatus.OCCLUDED_SEVERE, "kalman", last)

    def _bounded(
        self,
        o: _Outcome,
        t: KCTarget,
        prior: kalman.GaussianState,
        outside: bool,
        why: str | None,
    ) -> _Outcome:
        """Coasting is bounded (:func:`~pipeline.trackers.lifecycle.coast_ends`, ``why`` it ends):
        a prediction that leaves the frame, or ``max_missing_frames`` frames without a
        measurement, end in ``lost``, where the motion stops."""
        if o.status.is_occluded and why is not None:
            kf = stop(prior)
            out = BBox.from_center(kf.box.cx, kf.box.cy, t.last_rect.w, t.last_rect.h)
            ev = (*o.events, *transition(t.id, t.status, TargetStatus.LOST, why))
            return dataclasses.replace(
                o, kf=kf, out=out, status=TargetStatus.LOST, source="kalman", events=ev
            )
        if o.status == TargetStatus.LOST and outside:
            return dataclasses.replace(o, kf=stop(o.kf))  # a lost target stops at the border
        return o

    def _onset(
        self,
        o: _Outcome,
        t: KCTarget,
        prior: kalman.GaussianState,
        s: _Found,
        frame: int,
        ocfg: OcclusionConfig,
    ) -> _Outcome:
        """At an occlusion's onset the motion restarts from a line through the recent clean
        measurements (discarding those the occluder was dragging); the onset and a partial
        occlusion turning severe are events."""
        if o.status.is_occluded and t.status == TargetStatus.TRACKING:
            why = f"d={s.d:.2f}, area={s.area:.0f}"
            o = dataclasses.replace(
                o, events=(*o.events, *transition(t.id, t.status, o.status, why))
            )
            restart = coast_start(t.history, prior, frame, ocfg.rewind_frames)
            if restart is None:
                return o
            partial = o.status == TargetStatus.OCCLUDED_PARTIAL
            last = t.last_rect
            out = (
                restart.box
                if partial
                else BBox.from_center(restart.box.cx, restart.box.cy, last.w, last.h)
            )
            return dataclasses.replace(
                o, kf=restart, out=out, last_rect=out if partial else last, source="kalman-refit"
            )
        if o.status == TargetStatus.OCCLUDED_SEVERE and t.status == TargetStatus.OCCLUDED_PARTIAL:
            why = f"area={s.area:.0f}"
            return dataclasses.replace(
                o, events=(*o.events, *transition(t.id, t.status, o.status, why))
            )
        return o

    def track_target(
        self, image: np.ndarray, t: KCTarget, channel: str, frame: int
    ) -> tuple[KCTarget, TargetResult, list[Event]]:
        """One frame of Kalman-CAMShift for one target (the module doc's steps)."""
        ocfg = self.cfg.occlusion
        if t.noise_d > 0:
            ocfg = _noise_aware(ocfg, t.noise_d)
        kcfg = self.cfg.kalman
        F, Q = kalman.motion_model(kcfg)
        missing = t.status != TargetStatus.TRACKING
        prior = kalman.predict(hold_rates(t.kf, kcfg) if missing else t.kf, F, Q)
        pbox = prior.box
        s = self._search(image, t, pbox, ocfg, channel)
        min_area = t.reference.min_area(ocfg)
        ref_area = (t.last_rect if missing else pbox).area
        grade = grade_occlusion(s.d, s.area, min_area, ocfg, ref_area)
        if missing and grade == Grade.NONE and s.d >= ocfg.reacquire_distance:
            # hysteresis: not yet taken back
            grade = Grade.PARTIAL if s.area >= (min_area or 0.0) else Grade.SEVERE
        severe_run = next_severe_run(grade, t.severe_run)
        s = self._measured(s, grade, t, ref_area)
        o = self._outcome(grade, s, t, prior, severe_run, ocfg)
        h, w = image.shape[:2]
        missing_run = 0 if o.status == TargetStatus.TRACKING else t.missing_run + 1
        why = coast_ends(pbox, (h, w), missing_run, self.cfg.occlusion.max_missing_frames)
        o = self._bounded(o, t, prior, left_frame(pbox, (h, w)), why)
        o = self._onset(o, t, prior, s, frame, ocfg)
        history = t.history
        clean_match = s.d < 0.5 * ocfg.distance_threshold
        if o.status == TargetStatus.TRACKING and clean_match and s.box is not None:
            clean = (float(frame), s.box.cx, s.box.cy, s.box.w, s.box.h)
            history = (*t.history, clean)[-ocfg.history_frames :]
        reference = t.reference
        if o.status == TargetStatus.TRACKING and not missing:
            reference = reference.add(s.area, ocfg)
        new_t = dataclasses.replace(
            t,
            kf=o.kf,
            status=o.status,
            last_rect=o.last_rect,
            reference=reference,
            severe_run=0 if o.status == TargetStatus.TRACKING else severe_run,
            history=history,
            missing_run=missing_run,
        )
        return new_t, _result(t.id, o, s, pbox, min_area, new_t.severe_run), list(o.events)


def _result(
    tid: int, o: _Outcome, s: _Found, pbox: BBox, min_area: float | None, severe_run: int
) -> TargetResult:
    """What ``targets.csv`` and the recording show of one target this frame."""
    conf = {
        TargetStatus.TRACKING: 1.0 - s.d,
        TargetStatus.OCCLUDED_PARTIAL: 0.5,
        TargetStatus.OCCLUDED_SEVERE: 0.25,
    }.get(o.status, 0.0)
    diag = {
        "d": s.d,
        "area_px2": s.area,
        "min_area_px2": min_area if min_area is not None else float("nan"),
        "severe_run": float(severe_run),
    }
    overlays = {"prediction": pbox, "search": s.window}
    if s.box is not None:
        overlays["camshift"] = s.box
    return TargetResult(
        tid,
        o.out,
        o.status,
        o.source,
        {},
        1.0 - s.d * s.d,
        "frozen:paper-fixed-model",
        max(conf, 0.0),
        (),
        diag,
        overlays,
    )


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
    cfg_cs: CamShiftConfig,
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
