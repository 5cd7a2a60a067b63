"""``dual``: visible mean shift + IR level-set contour (Zhao, Bo, Yin 2012, §2.1-2.3), the default tracker.

Per frame and target, the paper's steps 2-5:

2. mean shift on the kernel-weighted HSV 16x4x4 histogram in the visible frame, from y0
   with scale h -> y1 (``pipeline.stages.meanshift``);
3. DRLSE level-set evolution in the IR frame around y1 (``pipeline.stages.contour``): the
   contour gives the precise position y2 and the size h_contour;
4. scale update ``h_new = (1 - a_s) h + a_s h_contour`` (eq. 7, ``dual.scale_rate``; only from
   a contour whose IR contrast is at least twice ``contour.min_contrast``: a fading
   contour shrinks before it fails), and the
   selective sub-model update (eq. 8-9, ``pipeline.stages.model_update``) of the histogram
   measured in the visible frame at y2 with h_new;
5. ``y0 = y2``, ``h = h_new``.

Modes by what the sequence has: both channels -> the above; IR only -> mean shift on an
IR intensity histogram plus the contour stage; visible only -> the ``meanshift`` engine
(mean shift with the +-10 % scale search).

Beyond the paper (each behind a flag, kept because the ablation in the issue's closing
note shows it helps):

* ``contour.warm_start``: the level set starts from the last good level-set function (not
  a failed one, which would pass its leak on), moved by the target's displacement since;
* ``dual.contour_checks``: leak, collapse, no component, too large and low contrast are
  detected and the mean-shift position is used instead (``targets.csv`` says which);
* ``dual.channel_weighting``: the visible channel is skipped when it carries no colour
  (dusk, deep shadow: too few pixels above ``colour_min_value``) and the IR contour is
  not trusted when its contrast has faded (thermal crossover): each channel is used for
  what it can still give;
* ``dual.motion_prior``: the shared Kalman stage predicts y0 (fast targets), coasts the
  target through frames where neither channel measures it, and re-acquires it near the
  prediction (a full occlusion by a static object). The coast starts from a line through
  the recent clean measurements (``pipeline.stages.motion``).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.io.sequence import FramePair
from pipeline.stages import kalman
from pipeline.stages.contour import ContourResult, LevelSetMemory, extract_contour
from pipeline.stages.histogram import appearance_bins, bhattacharyya, kernel_histogram, kernel_window, search_roi
from pipeline.stages.meanshift import mean_shift
from pipeline.stages.model_update import UpdateDecision, selective_update, should_update_model
from pipeline.stages.motion import coast_start, hold_rates
from pipeline.trackers import meanshift as ms_engine
from pipeline.types import BBox, Event, EventKind, FrameResult, InitTarget, TargetResult, TargetStatus


@dataclass(frozen=True)
class DualConfig:
    """The dual-channel tracker.

    Parameters
    ----------
    scale_rate : float
        a_s of eq. 7, weight of the contour's size in the scale update, in [0, 1];
        default 0.2. Increasing it follows size changes faster and passes contour noise on
        (0.5 let contours that lost a few px per frame against clutter shrink the scale
        unnoticed; 0.2 still follows a 3.3x approach over 200 frames).
    contour_checks : bool
        Detect contour failures and fall back to the mean-shift position; default True.
    channel_weighting : bool
        Skip the colour stage in dark frames and distrust faded IR contours; default True.
    motion_prior : bool
        Kalman prediction of y0, coasting and re-acquisition; default True.
    colour_min_value : int
        Visible pixels darker than this (HSV value 0..255) carry no colour, in [0, 255];
        default 40.
    colour_min_fraction : float
        The colour stage runs when at least this share of the kernel's pixels is bright
        enough, in [0, 1]; default 0.3.
    colour_min_rho : float
        Mean shift alone (no contour) counts as a measurement when its Bhattacharyya
        coefficient reaches this, in [0, 1]; default 0.6.
    occlusion_rho : float
        A target measured by colour alone (its contour failed, not from low contrast)
        whose colour match is below this is reported as partially occluded, in [0, 1];
        default 0.75.
    partial_area_ratio : float
        A target whose contour box is smaller than this share of its expected box is
        reported as partially occluded (model and scale frozen), in (0, 1); default 0.6.
    reacquire_rho : float
        An occluded target is taken back by colour alone (its IR has faded) only when the
        colour match reaches this, in [0, 1]; default 0.7.
    reacquire_gate_px_per_frame : float
        An occluded target is taken back only by a measurement within half a target size
        of its prediction, plus this many px per frame it has been missing, >= 0; default 1.
    max_missing_frames : int
        Frames without any measurement before the target is declared lost, >= 1; default 50.
    missing_search_scale : float
        While the target is missing, mean shift starts from the prediction with its search
        region this many times larger, in [1, 5]; default 2.
    history_frames : int
        Clean measurements kept for the coasting line fit, in [2, 100]; default 16.
    rewind_frames : int
        The coast restarts from that fit if its newest measurement is at most this old,
        in [0, 30]; default 8; 0 disables the restart.
    onset_frames : int
        The newest clean measurements left out of that fit, which an occluder may already
        have been cutting before the cut was detected, in [0, 10]; default 4.
    """

    scale_rate: float = 0.2
    contour_checks: bool = True
    channel_weighting: bool = True
    motion_prior: bool = True
    colour_min_value: int = 40
    colour_min_fraction: float = 0.3
    colour_min_rho: float = 0.6
    occlusion_rho: float = 0.75
    partial_area_ratio: float = 0.6
    reacquire_rho: float = 0.7
    reacquire_gate_px_per_frame: float = 1.0
    max_missing_frames: int = 50
    missing_search_scale: float = 2.0
    history_frames: int = 16
    rewind_frames: int = 8
    onset_frames: int = 4

    def __post_init__(self) -> None:
        for name in ("scale_rate", "colour_min_fraction", "colour_min_rho", "occlusion_rho", "reacquire_rho"):
            v = getattr(self, name)
            if not 0 <= v <= 1:
                raise ValueError(f"dual.{name} must be in [0, 1]; got {v!r}")
        if not 0 <= self.colour_min_value <= 255:
            raise ValueError(f"dual.colour_min_value must be in [0, 255]; got {self.colour_min_value!r}")
        if not self.reacquire_gate_px_per_frame >= 0:
            raise ValueError(f"dual.reacquire_gate_px_per_frame must be >= 0; got {self.reacquire_gate_px_per_frame!r}")
        if not (isinstance(self.max_missing_frames, int) and self.max_missing_frames >= 1):
            raise ValueError(f"dual.max_missing_frames must be an integer >= 1; got {self.max_missing_frames!r}")
        if not 0 < self.partial_area_ratio < 1:
            raise ValueError(f"dual.partial_area_ratio must be in (0, 1); got {self.partial_area_ratio!r}")
        if not 1 <= self.missing_search_scale <= 5:
            raise ValueError(f"dual.missing_search_scale must be in [1, 5]; got {self.missing_search_scale!r}")
        if not (isinstance(self.history_frames, int) and 2 <= self.history_frames <= 100):
            raise ValueError(f"dual.history_frames must be an integer in [2, 100]; got {self.history_frames!r}")
        if not (isinstance(self.onset_frames, int) and 0 <= self.onset_frames <= 10):
            raise ValueError(f"dual.onset_frames must be an integer in [0, 10]; got {self.onset_frames!r}")
        if not (isinstance(self.rewind_frames, int) and 0 <= self.rewind_frames <= 30):
            raise ValueError(f"dual.rewind_frames must be an integer in [0, 30]; got {self.rewind_frames!r}")


@dataclass(frozen=True)
class DualTarget:
    """Per-target state of the dual tracker."""

    id: int
    box: BBox  # last output box (centre y2)
    size: tuple[float, float]  # h of the paper: the kernel (w, h) used by the next mean shift
    q: np.ndarray  # appearance model of the mean-shift channel
    status: TargetStatus
    kf: kalman.GaussianState
    memory: LevelSetMemory | None = None  # the last good level set ...
    memory_center: tuple[float, float] = (0.0, 0.0)  # ... and the target centre when it was made
    history: tuple[tuple[float, float, float, float, float], ...] = ()
    missing: int = 0
    last_update: str = "none"


@dataclass(frozen=True)
class DualState:
    targets: tuple[DualTarget, ...]
    mode: str  # "dual" (visible + IR) or "ir"


def _colour_channel(frames: FramePair, mode: str) -> np.ndarray:
    img = frames.visible if mode == "dual" else frames.infrared
    assert img is not None
    return img


def init(frames: FramePair, targets: Sequence[InitTarget], cfg: object):
    """Start on frame 1: models from the initial boxes, a cold contour for the level-set memory."""
    if frames.infrared is None:  # visible only: the meanshift engine with its scale search
        return ms_engine.init(frames, targets, cfg)
    mode = "dual" if frames.visible is not None else "ir"
    image = _colour_channel(frames, mode)
    bins, m = appearance_bins(image, cfg.histogram)  # type: ignore[attr-defined]
    states, results = [], []
    for t in targets:
        q = kernel_histogram(bins, t.box, m)
        kf = kalman.init_state(t.box, cfg.kalman)  # type: ignore[attr-defined]
        c = extract_contour(frames.infrared, t.box, cfg.contour, cfg.levelset)  # type: ignore[attr-defined]
        states.append(DualTarget(t.id, t.box, (t.box.w, t.box.h), q, TargetStatus.TRACKING, kf,
                                 c.memory if c.box is not None else None, t.box.center,
                                 ((1.0, t.box.cx, t.box.cy, t.box.w, t.box.h),)))
        results.append(TargetResult(t.id, t.box, TargetStatus.TRACKING, "init", {"levelset": c.iterations}, 1.0,
                                    "none:init", 1.0, c.contour))
    return DualState(tuple(states), mode), FrameResult(frames.index, tuple(results))


def step(state, frames: FramePair, cfg: object):
    if isinstance(state, ms_engine.MeanShiftState):
        return ms_engine.step(state, frames, cfg)
    t0 = time.perf_counter()
    timing: dict[str, float] = {}
    new, results, events = [], [], []
    for t in state.targets:
        nt, r, ev = track_target(frames, t, cfg, state.mode, timing)
        new.append(nt)
        results.append(r)
        events += ev
    timing["dual"] = time.perf_counter() - t0
    return dataclasses.replace(state, targets=tuple(new)), FrameResult(frames.index, tuple(results), tuple(events), timing)


def _add(timing: dict[str, float], key: str, t0: float) -> float:
    now = time.perf_counter()
    timing[key] = timing.get(key, 0.0) + now - t0
    return now


def scale_update(h: tuple[float, float], h_contour: tuple[float, float], rate: float) -> tuple[float, float]:
    """Eq. 7: ``h_new = (1 - a) h + a h_contour`` for width and height."""
    return ((1 - rate) * h[0] + rate * h_contour[0], (1 - rate) * h[1] + rate * h_contour[1])


def colour_informative(image: np.ndarray, box: BBox, cfg: DualConfig) -> tuple[bool, float]:
    """Whether enough of the kernel's pixels are bright enough to carry colour (always True for IR)."""
    if image.ndim == 2 or not cfg.channel_weighting:
        return True, 1.0
    h, w = image.shape[:2]
    x0, y0, x1, y1 = search_roi(box, 0.0, w, h)
    patch = image[y0:y1, x0:x1]
    value = patch.max(axis=2)  # HSV value = max(B, G, R)
    frac = float(np.count_nonzero(value >= cfg.colour_min_value)) / max(value.size, 1)
    return frac >= cfg.colour_min_fraction, frac


def backprojection_peak(bins: np.ndarray, q: np.ndarray, size: tuple[float, float]) -> tuple[float, float] | None:
    """Centre (px of ``bins``) of the target-sized window holding the most model probability."""
    import cv2

    prob = q[bins].astype(np.float32)
    kw, kh = max(int(size[0]) | 1, 3), max(int(size[1]) | 1, 3)
    if prob.shape[0] < kh or prob.shape[1] < kw:
        return None
    dens = cv2.boxFilter(prob, -1, (kw, kh), borderType=cv2.BORDER_CONSTANT)
    r, c = np.unravel_index(int(np.argmax(dens)), dens.shape)
    return (c + 0.5, r + 0.5) if dens[r, c] > 0 else None


def _reference_size(t: DualTarget) -> tuple[float, float]:
    """(w, h) of the target in its recent clean frames (median), or its current size."""
    if len(t.history) >= 3:
        h = np.asarray(t.history, float)
        return float(np.median(h[:, 3])), float(np.median(h[:, 4]))
    return t.size


def reference_area(t: DualTarget) -> float:
    """Box area of the target in its recent clean frames (median), or of its current size."""
    if len(t.history) >= 3:
        h = np.asarray(t.history, float)
        return float(np.median(h[:, 3] * h[:, 4]))
    return t.size[0] * t.size[1]


def _near(candidate: BBox, predicted: BBox, t: DualTarget, dcfg: DualConfig) -> bool:
    """Within half a target size of the prediction, plus ``reacquire_gate_px_per_frame`` per frame missing."""
    ref = _reference_size(t)
    extra = dcfg.reacquire_gate_px_per_frame * t.missing
    return (abs(candidate.cx - predicted.cx) <= 0.5 * ref[0] + extra
            and abs(candidate.cy - predicted.cy) <= 0.5 * ref[1] + extra)


def _match_at(bins: np.ndarray, q: np.ndarray, box: BBox, roi0: tuple[int, int], cfg: object) -> float:
    """Bhattacharyya coefficient of the model and the kernel histogram inside ``box`` (frame px)."""
    win = kernel_window(bins.shape, box.cx - roi0[0], box.cy - roi0[1], box.w / 2, box.h / 2)
    if win.mass_fraction < cfg.meanshift.min_mass_fraction:  # type: ignore[attr-defined]
        return float("nan")
    p = np.bincount(bins[win.rows, win.cols], weights=win.k, minlength=q.size)
    total = p.sum()
    return bhattacharyya(p / total, q) if total > 0 else 0.0


def contour_usable(c: ContourResult, dcfg: DualConfig) -> bool:
    """Whether the contour gives the position: all checks pass (default); without
    ``channel_weighting`` the contrast test is not applied; without ``contour_checks`` any
    component overlapping the expected box is used, as the paper does."""
    if c.box is None:
        return False
    if not dcfg.contour_checks:
        return True
    if not dcfg.channel_weighting and c.reason == "low-contrast":
        return True
    return c.ok


def track_target(frames: FramePair, t: DualTarget, cfg: object, mode: str, timing: dict[str, float]):
    """One frame of the dual tracker for one target: (new state, result, events)."""
    dcfg: DualConfig = cfg.dual  # type: ignore[attr-defined]
    kcfg = cfg.kalman  # type: ignore[attr-defined]
    ir = frames.infrared
    assert ir is not None
    image = _colour_channel(frames, mode)
    H, W = ir.shape
    missing = t.status != TargetStatus.TRACKING
    clock = time.perf_counter()

    # motion prior (or the paper's y0 = previous y2)
    F, Q = kalman.motion_model(kcfg)
    Hm, Rm = kalman.measurement_model(kcfg)
    prior = kalman.predict(hold_rates(t.kf, kcfg) if missing else t.kf, F, Q)
    if dcfg.motion_prior:
        y0 = (float(prior.x[0]), float(prior.x[1]))
    else:
        y0 = t.box.center
    kernel = BBox.from_center(y0[0], y0[1], t.size[0], t.size[1])
    clock = _add(timing, "kalman", clock)

    # step 2: mean shift in the colour channel
    informative, bright = colour_informative(image, kernel, dcfg)
    rho1 = float("nan")
    ms_iters = 0
    y1 = y0
    bins = None
    roi0 = (0, 0)
    if informative:
        margin = cfg.meanshift.search_margin * (dcfg.missing_search_scale if missing else 1.0)  # type: ignore[attr-defined]
        x0, yy0, x1, yy1 = search_roi(kernel, margin, W, H)
        bins, _m = appearance_bins(np.ascontiguousarray(image[yy0:yy1, x0:x1]), cfg.histogram)  # type: ignore[attr-defined]
        roi0 = (x0, yy0)
        half = (t.size[0] / 2, t.size[1] / 2)
        ms = mean_shift(bins, t.q, (y0[0] - x0, y0[1] - yy0), half, cfg.meanshift)  # type: ignore[attr-defined]
        ms_iters = ms.iterations
        if missing:  # also start from where the model's colours are densest in the enlarged region
            peak = backprojection_peak(bins, t.q, t.size)
            if peak is not None:
                ms2 = mean_shift(bins, t.q, peak, half, cfg.meanshift)  # type: ignore[attr-defined]
                ms_iters += ms2.iterations
                if not ms2.no_support and (ms.no_support or ms2.rho > ms.rho):
                    ms = ms2
        if not ms.no_support:
            y1 = (ms.center[0] + x0, ms.center[1] + yy0)
            rho1 = ms.rho
        else:
            rho1 = 0.0
    clock = _add(timing, "meanshift", clock)

    # step 3: level-set contour in the IR frame around y1 (around y0 when the colour match is weak)
    colour_ok = informative and rho1 >= dcfg.colour_min_rho
    yc = y1 if (informative and rho1 >= dcfg.occlusion_rho) or not (dcfg.channel_weighting and dcfg.motion_prior) else y0
    expected = BBox.from_center(yc[0], yc[1], t.size[0], t.size[1])
    shift = (yc[0] - t.memory_center[0], yc[1] - t.memory_center[1])
    c: ContourResult = extract_contour(ir, expected, cfg.contour, cfg.levelset, t.memory, shift)  # type: ignore[attr-defined]
    contour_ok = contour_usable(c, dcfg)
    clock = _add(timing, "levelset", clock)

    # what was measured this frame: a clean measurement is a contour that passed its checks, has not shrunk
    # (occlusion) and, where there is colour, matches the model at its own position; or, where only the IR has
    # faded (crossover), a strong colour match. An occluded target is taken back only by a clean measurement
    # near its prediction.
    events: list[Event] = []
    rho_c = float("nan")
    if contour_ok and informative and bins is not None:
        assert c.box is not None
        rho_c = _match_at(bins, t.q, c.box, roi0, cfg)
    ref_area = reference_area(t)
    shrunk = contour_ok and c.box is not None and c.box.area < dcfg.partial_area_ratio * ref_area
    contour_clean = contour_ok and not shrunk and (not informative or np.isnan(rho_c) or rho_c >= dcfg.colour_min_rho)
    colour_clean = (mode == "dual" and informative and rho1 >= dcfg.occlusion_rho
                    and (c.reason == "low-contrast" or not dcfg.channel_weighting and not contour_ok))
    occluded_before = t.status != TargetStatus.TRACKING
    candidate = c.box if contour_clean else (BBox.from_center(y1[0], y1[1], t.size[0], t.size[1]) if colour_clean else None)
    if candidate is not None and occluded_before and not _near(candidate, prior.box, t, dcfg):
        candidate = None
    if candidate is not None and occluded_before and informative and not contour_clean and rho1 < dcfg.reacquire_rho:
        candidate = None
    if candidate is not None:
        status, missing_n = TargetStatus.TRACKING, 0
        if contour_clean:
            assert c.box is not None
            out, y2, h_contour, source = c.box, c.box.center, (c.box.w, c.box.h), "levelset"
        else:
            out, y2, h_contour, source = candidate, candidate.center, None, "meanshift"
    else:
        evidence = contour_ok or (informative and rho1 >= dcfg.colour_min_rho)
        missing_n = t.missing + 1
        if missing_n > dcfg.max_missing_frames:
            status = TargetStatus.LOST
        else:
            status = TargetStatus.OCCLUDED_PARTIAL if evidence else TargetStatus.OCCLUDED_SEVERE
        y2, h_contour, source = (float(prior.x[0]), float(prior.x[1])), None, "kalman"
        ref = _reference_size(t)
        out = BBox.from_center(y2[0], y2[1], ref[0], ref[1])
    measured = status == TargetStatus.TRACKING

    # step 4: scale update (eq. 7), only from an unoccluded contour with clear contrast
    size = t.size
    if h_contour is not None and abs(c.contrast) >= 2 * cfg.contour.min_contrast:  # type: ignore[attr-defined]
        size = scale_update(t.size, h_contour, dcfg.scale_rate)

    # step 4: selective sub-model update (eq. 8-9) with the histogram at y2 and the new scale
    rho2 = float("nan")
    q = t.q
    mu_cfg = cfg.model_update  # type: ignore[attr-defined]
    if not measured or bins is None or h_contour is None:
        decision = should_update_model(0.0, not measured, bins is not None, h_contour is not None, mu_cfg)
    else:
        cx, cy = y2[0] - roi0[0], y2[1] - roi0[1]
        win = kernel_window(bins.shape, cx, cy, size[0] / 2, size[1] / 2)
        if win.mass_fraction < cfg.meanshift.min_mass_fraction:  # type: ignore[attr-defined]
            decision = UpdateDecision(False, "window-cut-by-border")
        else:
            p = np.bincount(bins[win.rows, win.cols], weights=win.k, minlength=t.q.size)
            p = p / p.sum() if p.sum() > 0 else p
            rho2 = bhattacharyya(p, t.q)
            decision = should_update_model(rho2, False, True, True, mu_cfg)
            if decision.update:
                q = selective_update(t.q, p, mu_cfg)
    if not decision.update and t.last_update.startswith("updated") and decision.reason != "colour-uninformative":
        events.append(Event(EventKind.MODEL_FROZEN, f"T{t.id} model frozen ({decision.reason})", (t.id,)))
    clock = _add(timing, "model_update", clock)

    # motion: a clean measurement updates the filter; an occluded target coasts on the prediction, restarted
    # when the occlusion starts from a line through the recent clean measurements (leaving out the newest,
    # which the occluder may already have been cutting)
    history = t.history
    if measured:
        kf = kalman.update(prior, kalman.box_measurement(out), Hm, Rm).state
        if source == "levelset":
            history = (*t.history, (float(frames.index), out.cx, out.cy, out.w, out.h))[-dcfg.history_frames:]
    else:
        kf = prior
        if not occluded_before:
            restart = coast_start(t.history, prior, frames.index, dcfg.rewind_frames + dcfg.onset_frames,
                                  dcfg.onset_frames)
            if restart is not None:
                kf = restart
                ref = _reference_size(t)
                y2 = (float(kf.x[0]), float(kf.x[1]))
                out = BBox.from_center(y2[0], y2[1], ref[0], ref[1])
    _add(timing, "kalman", clock)

    # events
    if status != t.status:
        if status == TargetStatus.LOST:
            events.append(Event(EventKind.LOST, f"T{t.id} lost after {missing_n} frames without a measurement", (t.id,)))
        elif t.status == TargetStatus.LOST:
            events.append(Event(EventKind.REACQUIRED, f"T{t.id} re-acquired ({source})", (t.id,)))
        elif status.is_occluded and not t.status.is_occluded:
            events.append(Event(EventKind.OCCLUSION_START, f"T{t.id} {status} (rho={rho1:.2f}, contour {c.reason})", (t.id,)))
        elif not status.is_occluded and t.status.is_occluded:
            events.append(Event(EventKind.OCCLUSION_END, f"T{t.id} visible again ({source})", (t.id,)))

    conf = {TargetStatus.TRACKING: 1.0, TargetStatus.OCCLUDED_PARTIAL: 0.6, TargetStatus.OCCLUDED_SEVERE: 0.3}.get(status, 0.0)
    diag = {
        "rho_y1": rho1, "rho_y2": rho2, "rho_contour": rho_c, "contrast": c.contrast, "bright_fraction": bright,
        "missing": float(missing_n), "components": float(len(c.components)),
    }
    good = source == "levelset" and c.box is not None
    nt = dataclasses.replace(t, box=out, size=size, q=q, status=status, kf=kf,
                             memory=c.memory if good else t.memory,
                             memory_center=c.box.center if good and c.box is not None else t.memory_center,
                             history=history, missing=missing_n, last_update=str(decision))
    res = TargetResult(t.id, out, status, source, {"meanshift": ms_iters, "levelset": c.iterations},
                       rho2 if not np.isnan(rho2) else rho1, f"{decision}" + ("" if c.ok else f";contour-{c.reason}"),
                       conf, c.contour if c.box is not None else (), diag,
                       {"prediction": prior.box, "meanshift": BBox.from_center(y1[0], y1[1], t.size[0], t.size[1])})
    return nt, res, events
