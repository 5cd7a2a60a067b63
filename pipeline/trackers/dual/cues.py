"""The dual tracker's cues: the motion prior, the colour mean shift, the correlation filter and the
IR contour.

Each function measures one cue for one target and returns plain values; none decides (that
is ``decide.py``) or changes the target (``update.py``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.config import PipelineConfig
from pipeline.io.sequence import FramePair
from pipeline.stages import appearance as app
from pipeline.stages import detection, kalman
from pipeline.stages.detection import Background
from pipeline.stages.histogram import (
    appearance_bins,
    bhattacharyya,
    bright_fraction,
    ellipse_model,
    search_roi,
)
from pipeline.stages.meanshift import mean_shift
from pipeline.stages.motion import hold_rates
from pipeline.tracker_config import DualConfig
from pipeline.trackers.dual.decide import near_prediction
from pipeline.trackers.dual.state import DualTarget
from pipeline.types import BBox, TargetStatus


def add_time(timing: dict[str, float], key: str, t0: float) -> float:
    now = time.perf_counter()
    timing[key] = timing.get(key, 0.0) + now - t0
    return now


def colour_image(frames: FramePair, mode: str) -> np.ndarray:
    """The image the mean-shift cue works on: the visible frame, or the IR frame in the IR-only
    mode."""
    img = frames.infrared if mode == "ir" else frames.visible
    assert img is not None
    return img


def filter_images(frames: FramePair, mode: str) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The (visible, infrared) frames the correlation filter sees in a mode."""
    return (
        frames.visible if mode in ("dual", "visible") else None,
        frames.infrared if mode in ("dual", "ir") else None,
    )


def colour_informative(image: np.ndarray, box: BBox, cfg: DualConfig) -> tuple[bool, float]:
    """Whether enough of the kernel's pixels are bright enough to carry colour (always True for
    IR)."""
    if image.ndim == 2 or not cfg.channel_weighting:
        return True, 1.0
    h, w = image.shape[:2]
    x0, y0, x1, y1 = search_roi(box, 0.0, w, h)
    frac = bright_fraction(image[y0:y1, x0:x1], cfg.colour_min_value)
    return frac >= cfg.colour_min_fraction, frac


def backprojection_peak(
    bins: np.ndarray, q: np.ndarray, size: tuple[float, float]
) -> tuple[float, float] | None:
    """Centre (px of ``bins``) of the target-sized window holding the most model probability."""
    prob = q[bins].astype(np.float32)
    kw, kh = max(int(size[0]) | 1, 3), max(int(size[1]) | 1, 3)
    if prob.shape[0] < kh or prob.shape[1] < kw:
        return None
    dens = cv2.boxFilter(prob, -1, (kw, kh), borderType=cv2.BORDER_CONSTANT)
    r, c = np.unravel_index(int(np.argmax(dens)), dens.shape)
    return (c + 0.5, r + 0.5) if dens[r, c] > 0 else None


def match_at(
    bins: np.ndarray, q: np.ndarray, box: BBox, roi0: tuple[int, int], min_mass_fraction: float
) -> float:
    """Bhattacharyya coefficient of the model and the kernel histogram inside ``box`` (frame px);
    NaN when too little of the kernel lies in the region."""
    p, n, mass = ellipse_model(
        bins, box.cx - roi0[0], box.cy - roi0[1], box.w / 2, box.h / 2, q.size
    )
    if mass < min_mass_fraction:
        return float("nan")
    return bhattacharyya(p, q) if n > 0 else 0.0


@dataclass(frozen=True)
class ColourStep:
    """The motion prior and the mean shift of a target in one frame (the paper's step 2)."""

    t: DualTarget
    prior: kalman.GaussianState
    y0: tuple[float, float]
    y1: tuple[float, float]
    rho1: float
    informative: bool
    bright: float
    bins: np.ndarray | None
    roi0: tuple[int, int]
    ms_iters: int

    @property
    def box1(self) -> BBox:
        """The target's box at the mean-shift position y1."""
        return BBox.from_center(self.y1[0], self.y1[1], self.t.size[0], self.t.size[1])

    @property
    def box_prior(self) -> BBox:
        """The target's box at its predicted position."""
        return BBox.from_center(
            float(self.prior.x[0]), float(self.prior.x[1]), self.t.size[0], self.t.size[1]
        )


def colour_stage(
    frames: FramePair, t: DualTarget, cfg: PipelineConfig, mode: str, timing: dict[str, float]
) -> ColourStep:
    """Motion prior y0 (or the previous position) and mean shift in the colour channel -> y1."""
    dcfg: DualConfig = cfg.dual
    kcfg = cfg.kalman
    image = colour_image(frames, mode)
    H, W = image.shape[:2]
    missing = t.missing > 0 or t.status != TargetStatus.TRACKING
    clock = time.perf_counter()
    F, Q = kalman.motion_model(kcfg)
    prior = kalman.predict(hold_rates(t.kf, kcfg) if missing else t.kf, F, Q)
    y0 = (float(prior.x[0]), float(prior.x[1])) if dcfg.motion_prior else t.box.center
    kernel = BBox.from_center(y0[0], y0[1], t.size[0], t.size[1])
    clock = add_time(timing, "kalman", clock)

    informative, bright = colour_informative(image, kernel, dcfg)
    rho1, ms_iters, y1, bins, roi0 = float("nan"), 0, y0, None, (0, 0)
    if informative:
        margin = cfg.meanshift.search_margin * (dcfg.missing_search_scale if missing else 1.0)
        x0, yy0, x1, yy1 = search_roi(kernel, margin, W, H)
        bins, _m = appearance_bins(np.ascontiguousarray(image[yy0:yy1, x0:x1]), cfg.histogram)
        roi0 = (x0, yy0)
        half = (t.size[0] / 2, t.size[1] / 2)
        ms = mean_shift(bins, t.q, (y0[0] - x0, y0[1] - yy0), half, cfg.meanshift)
        ms_iters = ms.iterations
        if missing:  # also start from where the model's colours are densest in the enlarged region
            peak = backprojection_peak(bins, t.q, t.size)
            if peak is not None:
                ms2 = mean_shift(bins, t.q, peak, half, cfg.meanshift)
                ms_iters += ms2.iterations
                if not ms2.no_support and (ms.no_support or ms2.rho > ms.rho):
                    ms = ms2
        if not ms.no_support:
            y1 = (ms.center[0] + x0, ms.center[1] + yy0)
            rho1 = ms.rho
        else:
            rho1 = 0.0
    add_time(timing, "meanshift", clock)
    return ColourStep(t, prior, y0, y1, rho1, informative, bright, bins, roi0, ms_iters)


@dataclass(frozen=True)
class AppearanceCue:
    """The correlation filter's best detection of a target this frame."""

    box: BBox
    psr: float
    scale_factor: float
    redetected: bool  # found by the widened or whole-frame search, not at the prediction
    support: tuple[float, float] = (
        float("nan"),
        float("nan"),
    )  # (visible, IR) PSR of each channel at the peak


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
    ``center``, inside the frame: the nearest first; a larger grid is covered over successive calls
    (``turn``)."""
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


def frame_candidates(
    frames: FramePair,
    size: tuple[float, float],
    cfg: PipelineConfig,
    limit: int,
    background: Background | Callable[[], Background | None] | None = None,
) -> list[tuple[float, float]]:
    """Centres of the detector's regions (``detection`` section; its foreground method against
    ``background``, the sequence's (:mod:`pipeline.io.background`), or this frame's own without
    one) in the IR frame (the visible one without IR) about the target's size (a quarter to four
    times its area), the closest in size first: where a lost target may be anywhere. ``background``
    may be a function returning it (read only when needed)."""
    img = frames.infrared if frames.infrared is not None else frames.visible
    assert img is not None
    found = detection.detect(
        img,
        detection.infrared_only(cfg.detection),
        background() if callable(background) else background,
    ).regions
    area = max(size[0] * size[1], 1.0)
    near = [r for r in found if 0.25 <= r.box.area / area <= 4.0]
    near.sort(key=lambda r: abs(math.log(max(r.box.area, 1.0) / area)))
    return [r.box.center for r in near[:limit]]


def last_seen(t: DualTarget, dcfg: DualConfig) -> tuple[float, float] | None:
    """Centre of the target's last clean measurement, where the widened search also looks (None
    without one or with ``redetect_last_seen`` off)."""
    if not dcfg.redetect_last_seen or not t.history:
        return None
    return (t.history[-1][1], t.history[-1][2])


def recent_speed(t: DualTarget) -> float:
    """The target's speed over its recent clean measurements, px per frame (0 with fewer than two)."""
    if len(t.history) < 2:
        return 0.0
    a, b = t.history[0], t.history[-1]
    return math.hypot(b[1] - a[1], b[2] - a[2]) / max(b[0] - a[0], 1.0)


def taken_back(d: app.Detection, cs: ColourStep, dcfg: DualConfig) -> bool:
    """The filter's detection ``d`` of a missing target is one that rule 7 of the decision takes
    back: at ``psr_reacquire`` and near the prediction
    (:func:`pipeline.trackers.dual.decide.near_prediction`)."""
    predicted = (float(cs.prior.x[0]), float(cs.prior.x[1]))
    return d.psr >= dcfg.psr_reacquire and near_prediction(
        d.center, predicted, cs.t.reference_size, cs.t.missing, dcfg
    )


def appearance_cue(
    frames: FramePair,
    cs: ColourStep,
    cfg: PipelineConfig,
    mode: str,
    timing: dict[str, float],
    frame_index: int,
    background: Background | Callable[[], Background | None] | None = None,
) -> AppearanceCue | None:
    """Detect the target with its filter at its prediction (and at the colour cue's position when
    that is elsewhere); a missing target is also looked for, every ``redetect_every_frames``, over
    a region widening with the missing frames and, after ``redetect_global_after_frames``, at the
    detector's regions of the whole frame, at most ``redetect_candidates`` places a frame; the
    widening region is searched around the prediction and around where the target was last seen;
    ``background`` is the detector's (see :func:`frame_candidates`). None without a filter."""
    dcfg: DualConfig = cfg.dual
    acfg: app.AppearanceConfig = cfg.appearance
    t = cs.t
    if not dcfg.appearance_cue or t.appearance is None:
        return None
    clock = time.perf_counter()
    vis, ir = filter_images(frames, mode)
    size = t.app_size
    with_scale = frame_index % acfg.scale_every_frames == 0
    best = app.detect(t.appearance, vis, ir, cs.y0, acfg, size=size, with_scale=with_scale)
    redetected = False
    missing = t.missing > 0
    if (
        cs.informative
        and cs.rho1 >= dcfg.colour_min_rho
        and best.psr < dcfg.psr_reacquire
        and (
            abs(cs.y1[0] - cs.y0[0]) > dcfg.agree_fraction * size[0]
            or abs(cs.y1[1] - cs.y0[1]) > dcfg.agree_fraction * size[1]
        )
    ):
        # the colour found the target away from its prediction (a turn): the filter looks there too
        d = app.detect(t.appearance, vis, ir, cs.y1, acfg, size=size, with_scale=with_scale)
        if d.psr > best.psr:
            best = d
    # a missing target is searched for unless the filter finds it where rule 7 of the decision
    # takes it back (a confident peak elsewhere in the window, on something the filter learned
    # while the target was hidden, does not stop the search)
    if missing and dcfg.redetect and not taken_back(best, cs, dcfg):
        H, W = frames.shape
        cands = []
        if cs.informative and not math.isnan(cs.rho1):
            cands.append(cs.y1)
        if t.missing % dcfg.redetect_every_frames == 0:
            turn = t.missing // dcfg.redetect_every_frames
            if t.missing >= dcfg.redetect_global_after_frames:
                cands += frame_candidates(frames, size, cfg, dcfg.redetect_candidates, background)
            else:
                rate = max(
                    dcfg.redetect_radius_px_per_frame,
                    recent_speed(t) if dcfg.redetect_last_seen else 0.0,
                )
                radius = 0.5 * math.hypot(*size) + rate * t.missing
                centres = [cs.y0]
                seen = last_seen(t, dcfg)
                if seen is not None and math.hypot(
                    seen[0] - cs.y0[0], seen[1] - cs.y0[1]
                ) > 0.5 * min(size):
                    # a target that turned or stopped while hidden is near where it was last seen,
                    # not ahead
                    centres.append(seen)
                per = -(-dcfg.redetect_candidates // len(centres))
                for c0 in centres:
                    cands += region_candidates(c0, radius, size, W, H, per, turn)
        for c in cands:
            d = app.detect(t.appearance, vis, ir, c, acfg, size=size, with_scale=False)
            if d.psr > best.psr:
                best, redetected = d, True
        if redetected:  # the size at the place found
            best = app.detect(t.appearance, vis, ir, best.center, acfg, size=size)
    add_time(timing, "appearance", clock)
    H, W = frames.shape
    cx, cy = min(max(best.center[0], 0.0), float(W)), min(max(best.center[1], 0.0), float(H))
    box = BBox.from_center(cx, cy, best.size[0], best.size[1])
    return AppearanceCue(box, best.psr, best.scale_factor, redetected, best.support)
