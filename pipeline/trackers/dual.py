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

Known weakness (measured over seeds 0-4 of the synthetic scenes): the IR contour is
warm-started where the mean shift went, so when the colour model follows a person into a
cast shadow (``shadows`` seeds 2-4, the match stays at rho 0.82-0.90) the contour follows
it and the target is lost (P@20 0.78 / 0.43 / 0.48). Moving the warm start by the motion
prior instead, with the region covering both positions, fixed those three (P@20 1.000)
but lost ``hot-distractor`` and ``occluder`` (1.0 -> 0.52, 0.98 -> 0.53), where the IR
merges with a warm neighbour and the colour is the channel that is right; the two cues
disagree by the same few pixels in both cases, so deciding which to follow needs more
than their distance (a second contour from the motion prior where the cues part by over a
tenth of the width, kept when it fits the predicted box better, fixed seeds 2 and 3 but
cost ``fast`` 0.12 AUC). Not the model update: with it off the three seeds fail alike;
``histogram.value_bins=1`` (no brightness bins) fixed seeds 2 and 4, not 3.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from statistics import median

import numpy as np

from pipeline.io.sequence import FramePair
from pipeline.stages import kalman
from pipeline.stages.contour import ContourResult, LevelSetMemory, extract_contour
from pipeline.stages.merge import (associate, association_cost, choose_foreground_stable, eq11, inside_blob, kmeans_shares,
                                   lookalike_sets, merge_groups)
from pipeline.stages.histogram import (appearance_bins, bhattacharyya, bright_fraction, ellipse_model, kernel_histogram,
                                       search_roi)
from pipeline.stages.meanshift import mean_shift
from pipeline.stages.model_update import UpdateDecision, selective_update, should_update_model
from pipeline.stages.motion import coast_start, hold_rates, stop
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
    colour_trust_rho : float
        Beyond the paper: a tracked (not occluded) target whose contour failed its checks for
        any reason is still measured by its mean-shift position when the colour match
        reaches this (no scale or model update from such a frame), in [0, 1]; default 0.85,
        1 disables it. Without it a contour that lost a fast target's legs, with colour at
        rho 0.9, let the track coast on its prediction and lose the target.
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
    merge_handling : bool
        Handle mutual occlusion as the paper does (eq. 10 merge test, foreground and
        occluded roles, one level set over the merged blob, split and re-association);
        default True. False tracks every target independently.
    merge_position : str
        Where the members of a merge are placed: ``eq11`` (the paper: the foreground at
        its mean-shift position, an occluded target mirrored about the blob centre),
        ``motion`` (the foreground as in the paper, occluded targets at their Kalman
        prediction: the paper's future work, for long occlusions) or ``auto`` (default,
        beyond the paper): look-alikes (see ``lookalike_rho``) by k-means on the merged
        blob started from their predictions; every member whose own colour is clearly seen
        (``merge_visible_rho``), and not where a better-matching member already is, at its
        mean-shift position; the rest of a pair by eq. 11 (kept inside the blob) while the
        blob is wider than the foreground alone, else on their motion state. Measured on
        the synthetic crossings: ``edges`` (placing members on the blob's edges ordered by
        their predictions) swapped crossing identities and ``share`` (the foreground from
        its share of the blob) was worse than the paper; neither was kept.
    lookalike_rho : float
        Two targets whose colour models match at least this well (eq. 3) are look-alikes,
        whose mean shifts cannot tell them apart inside a merge, in [0, 1]; default 0.85.
    merge_visible_rho : float
        In ``auto``, a merged member whose colour match reaches this is measured by its own
        mean shift, in [0, 1]; default 0.75 (0.6 and 0.68 lowered purity on group3; with
        ``merge_inside_blob``, mean purity over crossing3, meet-part and group3 of seeds
        0-4 was 0.991 at 0.75, 0.987 at 0.7 and 0.981 at 0.65).
    merge_inside_blob : bool
        Beyond the paper: a merged member placed on its motion state is reported inside
        the merged blob's box (moved the least distance that puts its box inside it; its
        motion state is left as it is), since a member of a merge is part of its blob.
        Default True. Measured on group3, seeds 0-2: identity purity 0.925 / 0.928 / 0.937
        with 2 / 2 / 0 ID switches without it, 0.988 / 0.992 / 0.978 with 0 switches with
        it (a member hidden behind the other two coasted on a near-zero velocity while
        the group drifted); the other multi-target scenes unchanged or better (crossing3
        seed 1 0.990 -> 0.995). Correcting the motion state with the moved position as
        well lowered group3 to 0.955-0.957.
    split_hold_frames : int
        Beyond the paper: for this many frames after targets split, they merge again only
        when their boxes overlap deeply (``remerge_scale``), so two people parting at the
        edge of the merge test do not flicker merge / split / merge, >= 0; default 3.
    remerge_scale : float
        The merge test's half-sizes are scaled by this during that hold, in (0, 1]; default 0.8.
    kmeans_iterations : int
        Passes of the k-means that locates look-alikes in a merged blob, in [1, 50]; default 5.
    role_margin : float
        The foreground keeps its role until another member's colour match is higher by
        this much, in [0, 1]; default 0.05 (look-alikes do not swap roles every frame).
    split_min_area_fraction : float
        A component of the merged blob counts as a separated target when its box covers
        at least this share of the smallest member's usual box, in (0, 1); default 0.3.
    association_motion_weight : float
        Weight of the distance to each target's prediction (in target sizes) against the
        colour dissimilarity when blobs are re-associated after a split, >= 0; default 1.
        0 is the paper (colour only), which cannot separate look-alikes.
    """

    scale_rate: float = 0.2
    contour_checks: bool = True
    channel_weighting: bool = True
    motion_prior: bool = True
    colour_min_value: int = 40
    colour_min_fraction: float = 0.3
    colour_min_rho: float = 0.6
    occlusion_rho: float = 0.75
    colour_trust_rho: float = 0.85
    partial_area_ratio: float = 0.6
    reacquire_rho: float = 0.7
    reacquire_gate_px_per_frame: float = 1.0
    max_missing_frames: int = 50
    missing_search_scale: float = 2.0
    history_frames: int = 16
    rewind_frames: int = 8
    onset_frames: int = 4
    merge_handling: bool = True
    merge_position: str = "auto"
    role_margin: float = 0.05
    split_min_area_fraction: float = 0.3
    association_motion_weight: float = 1.0
    lookalike_rho: float = 0.85
    merge_visible_rho: float = 0.75
    merge_inside_blob: bool = True
    split_hold_frames: int = 3
    remerge_scale: float = 0.8
    kmeans_iterations: int = 5

    def __post_init__(self) -> None:
        for name in ("scale_rate", "colour_min_fraction", "colour_min_rho", "occlusion_rho", "colour_trust_rho",
                     "reacquire_rho"):
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
        if self.merge_position not in ("auto", "eq11", "motion"):
            raise ValueError(f"dual.merge_position must be auto, eq11 or motion; got {self.merge_position!r}")
        for name in ("lookalike_rho", "merge_visible_rho"):
            v = getattr(self, name)
            if not 0 <= v <= 1:
                raise ValueError(f"dual.{name} must be in [0, 1]; got {v!r}")
        if not (isinstance(self.kmeans_iterations, int) and 1 <= self.kmeans_iterations <= 50):
            raise ValueError(f"dual.kmeans_iterations must be an integer in [1, 50]; got {self.kmeans_iterations!r}")
        if not 0 <= self.role_margin <= 1:
            raise ValueError(f"dual.role_margin must be in [0, 1]; got {self.role_margin!r}")
        if not 0 < self.split_min_area_fraction < 1:
            raise ValueError(f"dual.split_min_area_fraction must be in (0, 1); got {self.split_min_area_fraction!r}")
        if not self.association_motion_weight >= 0:
            raise ValueError(f"dual.association_motion_weight must be >= 0; got {self.association_motion_weight!r}")
        if not (isinstance(self.split_hold_frames, int) and self.split_hold_frames >= 0):
            raise ValueError(f"dual.split_hold_frames must be an integer >= 0; got {self.split_hold_frames!r}")
        if not 0 < self.remerge_scale <= 1:
            raise ValueError(f"dual.remerge_scale must be in (0, 1]; got {self.remerge_scale!r}")
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
    split_frame: int = -1_000_000  # frame of the last split from a merge (re-merge hysteresis)


@dataclass(frozen=True)
class GroupMemory:
    """The level set of a merged group, kept for the next frame's warm start."""

    members: tuple[int, ...]
    memory: LevelSetMemory
    center: tuple[float, float]
    foreground: int


@dataclass(frozen=True)
class DualState:
    targets: tuple[DualTarget, ...]
    mode: str  # "dual" (visible + IR) or "ir"
    groups: tuple[GroupMemory, ...] = ()


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
    dcfg: DualConfig = cfg.dual  # type: ignore[attr-defined]
    steps = {t.id: colour_stage(frames, t, cfg, state.mode, timing) for t in state.targets}
    # eq. 10 on the mean-shift positions; a member of a merge is tested at its prediction instead, since its
    # mean shift may sit on whoever hides it (a look-alike, above all) and would hold the group together
    live = {i: cs.box_prior if cs.t.status == TargetStatus.MERGED else cs.box1
            for i, cs in steps.items() if cs.t.status != TargetStatus.LOST}
    held = {i for i, cs in steps.items() if frames.index - cs.t.split_frame <= dcfg.split_hold_frames}
    groups = merge_groups(live, held, dcfg.remerge_scale) if dcfg.merge_handling and len(live) > 1 else []
    in_group = {i for g in groups for i in g}
    done: dict[int, tuple[DualTarget, TargetResult, list[Event]]] = {}
    new_groups = []
    for g in groups:
        out, mem = finish_group(frames, [steps[i] for i in g], cfg, state.mode, timing, state.groups)
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
        done[i] = finish_single(frames, cs, cfg, state.mode, timing, start=start, events_in=ev)
    new, results, events = [], [], []
    for t in state.targets:
        nt, r, ev = done[t.id]
        new.append(nt)
        results.append(r)
        events += ev
    timing["dual"] = time.perf_counter() - t0
    return (dataclasses.replace(state, targets=tuple(new), groups=tuple(new_groups)),
            FrameResult(frames.index, tuple(results), tuple(events), timing))


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
    frac = bright_fraction(image[y0:y1, x0:x1], cfg.colour_min_value)
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
    """(w, h) of the target in its recent clean frames (median), or its current size. (``statistics.median``
    on these 16 numbers gives np.median's value at a tenth of the cost.)"""
    if len(t.history) >= 3:
        return median(r[3] for r in t.history), median(r[4] for r in t.history)
    return t.size


def reference_area(t: DualTarget) -> float:
    """Box area of the target in its recent clean frames (median), or of its current size."""
    if len(t.history) >= 3:
        return median(r[3] * r[4] for r in t.history)
    return t.size[0] * t.size[1]


def _near(candidate: BBox, predicted: BBox, t: DualTarget, dcfg: DualConfig) -> bool:
    """Within half a target size of the prediction, plus ``reacquire_gate_px_per_frame`` per frame missing."""
    ref = _reference_size(t)
    extra = dcfg.reacquire_gate_px_per_frame * t.missing
    return (abs(candidate.cx - predicted.cx) <= 0.5 * ref[0] + extra
            and abs(candidate.cy - predicted.cy) <= 0.5 * ref[1] + extra)


def _match_at(bins: np.ndarray, q: np.ndarray, box: BBox, roi0: tuple[int, int], cfg: object) -> float:
    """Bhattacharyya coefficient of the model and the kernel histogram inside ``box`` (frame px)."""
    p, n, mass_fraction = ellipse_model(bins, box.cx - roi0[0], box.cy - roi0[1], box.w / 2, box.h / 2, q.size)
    if mass_fraction < cfg.meanshift.min_mass_fraction:  # type: ignore[attr-defined]
        return float("nan")
    return bhattacharyya(p, q) if n > 0 else 0.0


def _outside(box: BBox, shape: tuple[int, ...]) -> bool:
    """Less than a quarter of the box lies inside the frame."""
    return box.clip(shape[1], shape[0]).area < 0.25 * box.area


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


@dataclass(frozen=True)
class ColourStep:
    """What the first half of a frame (prediction and mean shift, the paper's step 2) found for a target."""

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
        return BBox.from_center(float(self.prior.x[0]), float(self.prior.x[1]), self.t.size[0], self.t.size[1])


def colour_stage(frames: FramePair, t: DualTarget, cfg: object, mode: str, timing: dict[str, float]) -> ColourStep:
    """Motion prior y0 (or the previous y2) and mean shift in the colour channel -> y1 (step 2)."""
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

    return ColourStep(t, prior, y0, y1, rho1, informative, bright, bins, roi0, ms_iters)


def track_target(frames: FramePair, t: DualTarget, cfg: object, mode: str, timing: dict[str, float]):
    """One frame of the dual tracker for one independent target: (new state, result, events)."""
    return finish_single(frames, colour_stage(frames, t, cfg, mode, timing), cfg, mode, timing)


def finish_single(frames: FramePair, cs: ColourStep, cfg: object, mode: str, timing: dict[str, float],
                  start: tuple[float, float] | None = None, events_in: list[Event] | None = None):
    """Steps 3-5 for one target: contour, measurement decision, scale, model and motion updates.

    ``start`` forces where the contour starts (cold) after a split, which starts the re-merge hold."""
    dcfg: DualConfig = cfg.dual  # type: ignore[attr-defined]
    kcfg = cfg.kalman  # type: ignore[attr-defined]
    ir = frames.infrared
    assert ir is not None
    t, prior, y0, y1, rho1 = cs.t, cs.prior, cs.y0, cs.y1, cs.rho1
    informative, bright, bins, roi0, ms_iters = cs.informative, cs.bright, cs.bins, cs.roi0, cs.ms_iters
    Hm, Rm = kalman.measurement_model(kcfg)
    clock = time.perf_counter()

    # step 3: level-set contour in the IR frame around y1 (around y0 when the colour match is weak)
    colour_ok = informative and rho1 >= dcfg.colour_min_rho
    yc = y1 if (informative and rho1 >= dcfg.occlusion_rho) or not (dcfg.channel_weighting and dcfg.motion_prior) else y0
    memory = t.memory
    if start is not None:
        yc, memory = start, None
    expected = BBox.from_center(yc[0], yc[1], t.size[0], t.size[1])
    shift = (yc[0] - t.memory_center[0], yc[1] - t.memory_center[1])
    c: ContourResult = extract_contour(ir, expected, cfg.contour, cfg.levelset, memory, shift)  # type: ignore[attr-defined]
    contour_ok = contour_usable(c, dcfg)
    clock = _add(timing, "levelset", clock)

    # what was measured this frame: a clean measurement is a contour that passed its checks, has not shrunk
    # (occlusion) and, where there is colour, matches the model at its own position; or, where only the IR has
    # faded (crossover), a strong colour match. An occluded target is taken back only by a clean measurement
    # near its prediction.
    events: list[Event] = list(events_in or [])
    rho_c = float("nan")
    if contour_ok and informative and bins is not None:
        assert c.box is not None
        rho_c = _match_at(bins, t.q, c.box, roi0, cfg)
    ref_area = reference_area(t)
    shrunk = contour_ok and c.box is not None and c.box.area < dcfg.partial_area_ratio * ref_area
    contour_clean = contour_ok and not shrunk and (not informative or np.isnan(rho_c) or rho_c >= dcfg.colour_min_rho)
    occluded_before = t.status != TargetStatus.TRACKING
    colour_clean = (mode == "dual" and informative and rho1 >= dcfg.occlusion_rho
                    and (c.reason == "low-contrast" or not dcfg.channel_weighting and not contour_ok
                         or not contour_clean and not occluded_before and dcfg.channel_weighting
                         and rho1 >= dcfg.colour_trust_rho and dcfg.colour_trust_rho < 1))
    candidate = c.box if contour_clean else (BBox.from_center(y1[0], y1[1], t.size[0], t.size[1]) if colour_clean else None)
    if candidate is not None and occluded_before and start is None and not _near(candidate, prior.box, t, dcfg):
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
        if missing_n > dcfg.max_missing_frames or _outside(prior.box, ir.shape):
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
        p, _, mass_fraction = ellipse_model(bins, cx, cy, size[0] / 2, size[1] / 2, t.q.size)
        if mass_fraction < cfg.meanshift.min_mass_fraction:  # type: ignore[attr-defined]
            decision = UpdateDecision(False, "window-cut-by-border")
        else:
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
        kf = kalman.correct(prior, kalman.box_measurement(out), Hm, Rm, kcfg).state
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
        if status == TargetStatus.LOST:  # a lost target stays where it was last believed to be
            kf = stop(kf)
    _add(timing, "kalman", clock)

    # events
    if status != t.status:
        if status == TargetStatus.LOST:
            why = "left the frame" if _outside(prior.box, ir.shape) else f"{missing_n} frames without a measurement"
            events.append(Event(EventKind.LOST, f"T{t.id} lost ({why})", (t.id,)))
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
                             history=history, missing=missing_n, last_update=str(decision),
                             split_frame=frames.index if start is not None else t.split_frame)
    res = TargetResult(t.id, out, status, source, {"meanshift": ms_iters, "levelset": c.iterations},
                       rho2 if not np.isnan(rho2) else rho1, f"{decision}" + ("" if c.ok else f";contour-{c.reason}"),
                       conf, c.contour if c.box is not None else (), diag,
                       {"prediction": prior.box, "meanshift": BBox.from_center(y1[0], y1[1], t.size[0], t.size[1])})
    return nt, res, events


def _union(boxes: list[BBox]) -> BBox:
    x0 = min(b.x for b in boxes)
    y0 = min(b.y for b in boxes)
    return BBox(x0, y0, max(b.x2 for b in boxes) - x0, max(b.y2 for b in boxes) - y0)


def finish_group(frames: FramePair, css: list[ColourStep], cfg: object, mode: str, timing: dict[str, float],
                 memories: tuple[GroupMemory, ...]):
    """A merged group (steps 4-9 of the paper's multi-target algorithm).

    One level set over the merged blob, started from the members' positions. If it shows
    a separate blob for every member, the group splits: blobs are re-associated globally
    (colour, plus distance to each prediction) and every member continues on its own. Else
    the group stays merged: the foreground (best colour match) keeps its mean-shift
    position; an occluded member is placed by eq. 11 or by its motion state
    (``dual.merge_position``); no scale or model update while merged.
    """
    dcfg: DualConfig = cfg.dual  # type: ignore[attr-defined]
    kcfg = cfg.kalman  # type: ignore[attr-defined]
    ir = frames.infrared
    assert ir is not None
    clock = time.perf_counter()
    ids = tuple(cs.t.id for cs in css)
    union = _union([cs.box1 for cs in css] + [cs.box_prior for cs in css if cs.t.status == TargetStatus.MERGED])
    group_cfg = dataclasses.replace(cfg.contour, max_area_ratio=50.0, max_dimension_ratio=50.0)  # type: ignore[attr-defined]
    prev = next((m for m in memories if m.members == ids), None)
    shift = (union.cx - prev.center[0], union.cy - prev.center[1]) if prev else (0.0, 0.0)
    c = extract_contour(ir, union, group_cfg, cfg.levelset, prev.memory if prev else None, shift,  # type: ignore[attr-defined]
                        cold_init=union.scaled(1.15), part_width=min(cs.t.size[0] for cs in css))
    clock = _add(timing, "levelset", clock)
    min_area = dcfg.split_min_area_fraction * min(reference_area(cs.t) for cs in css)
    blobs = [b for b in c.components if b.area >= min_area and b.intersect(union.scaled(1.2)).area > 0]
    was_merged = all(cs.t.status == TargetStatus.MERGED for cs in css)
    out: dict[int, tuple[DualTarget, TargetResult, list[Event]]] = {}

    if len(blobs) >= len(css):  # split: every member has its own blob again
        rho = np.full((len(css), len(blobs)), np.nan)
        dist = np.zeros((len(css), len(blobs)))
        scale = np.array([np.hypot(*cs.t.size) for cs in css])
        for i, cs in enumerate(css):
            for j, b in enumerate(blobs):
                if cs.informative and cs.bins is not None:
                    rho[i, j] = _match_at(cs.bins, cs.t.q, b.with_center(b.cx, b.cy), cs.roi0, cfg)
                dist[i, j] = np.hypot(b.cx - cs.y0[0], b.cy - cs.y0[1])
        pairs = associate(association_cost(rho, dist, scale, dcfg.association_motion_weight))
        text = ", ".join(f"T{css[i].t.id}->blob at ({blobs[j].cx:.0f},{blobs[j].cy:.0f})" for i, j in pairs)
        for i, j in pairs:
            cs = css[i]
            ev = [Event(EventKind.SPLIT, f"T{cs.t.id} split from {'+'.join(f'T{k}' for k in ids)}; re-associated: {text}",
                        (cs.t.id,))] if i == pairs[0][0] else []
            t = dataclasses.replace(cs.t, memory=None, status=TargetStatus.OCCLUDED_PARTIAL)
            out[cs.t.id] = finish_single(frames, dataclasses.replace(cs, t=t), cfg, mode, timing,
                                         start=blobs[j].center, events_in=ev)
        return out, None

    # still merged; a group contour without contrast (leaked into the background) places nobody
    group_ok = c.box is not None and abs(c.contrast) >= cfg.contour.min_contrast  # type: ignore[attr-defined]
    y2 = c.box.center if c.box is not None else union.center
    fg_id = choose_foreground_stable({cs.t.id: cs.rho1 if cs.informative else float("nan") for cs in css},
                                     prev.foreground if prev else None, dcfg.role_margin,
                                     {cs.t.id: float(np.hypot(cs.y1[0] - y2[0], cs.y1[1] - y2[1])) for cs in css})
    fg = next(cs for cs in css if cs.t.id == fg_id)
    Hm, Rm = kalman.measurement_model(kcfg)
    blob_wider = group_ok and c.box is not None and c.box.w > 1.2 * fg.t.size[0]
    blob_ratio = c.box.area / sum(reference_area(cs.t) for cs in css) if c.box is not None else float("nan")
    events: list[Event] = []
    if not was_merged:
        roles = ", ".join(f"T{cs.t.id} {'foreground' if cs.t.id == fg_id else 'occluded'}" for cs in css)
        events.append(Event(EventKind.MERGE, f"{'+'.join(f'T{k}' for k in ids)} merged ({roles})", ids))
    elif prev is not None and prev.foreground != fg_id:
        events.append(Event(EventKind.MERGE, f"T{fg_id} now in front of {'+'.join(f'T{k}' for k in ids if k != fg_id)}", ids))
    # beyond the paper ("auto"): look-alikes located by k-means on the blob; any other member whose own
    # colour is clearly seen (and not where a better-matching member already is) measured by its mean shift
    placed: dict[int, tuple[tuple[float, float], str]] = {}
    if dcfg.merge_position == "auto":
        alike = {i for g in lookalike_sets({cs.t.id: cs.t.q for cs in css if cs.informative}, dcfg.lookalike_rho)
                 for i in g}
        if alike and group_ok and c.box is not None and c.memory is not None:
            mask = _main_blob(c.memory.phi, union, c.memory.origin)
            members = [cs for cs in css if cs.t.id in alike]
            if mask is not None:
                cents = kmeans_shares(mask, c.memory.origin, [(float(cs.prior.x[0]), float(cs.prior.x[1])) for cs in members],
                                      [_reference_size(cs.t) for cs in members], dcfg.kmeans_iterations)
                for cs, cen in zip(members, cents, strict=True):
                    if cen is not None:
                        placed[cs.t.id] = (cen, "merge-kmeans")
        near = 0.5 * min(cs.t.size[0] for cs in css)
        for cs in sorted(css, key=lambda cs: -cs.rho1 if cs.informative else 1.0):
            if cs.t.id in placed or not cs.informative or (cs.t.id != fg_id and cs.rho1 < dcfg.merge_visible_rho):
                continue
            if all(np.hypot(cs.y1[0] - p[0], cs.y1[1] - p[1]) > near for p, _ in placed.values()):
                placed[cs.t.id] = (cs.y1, "merge-foreground" if cs.t.id == fg_id else "merge-visible")
    for cs in css:
        t = cs.t
        ref = _reference_size(t)
        role = 1.0 if t.id == fg_id else 2.0
        missing_n = 0
        if t.id in placed:
            y, source = placed[t.id]
        elif t.id == fg_id:
            y, source = cs.y1, "merge-foreground"
        elif len(css) == 2 and (dcfg.merge_position == "eq11" or (dcfg.merge_position == "auto" and blob_wider)):
            y, source = eq11(y2, fg.y1), "merge-eq11"
            if c.box is not None:  # the mirrored position stays inside the blob it was mirrored in
                y = inside_blob(y, ref, c.box)
        else:
            y, source = (float(cs.prior.x[0]), float(cs.prior.x[1])), "merge-motion"
            if dcfg.merge_inside_blob and group_ok and c.box is not None:
                y = inside_blob(y, ref, c.box)  # reported inside the blob; the motion state is left as it is
        box = BBox.from_center(y[0], y[1], ref[0], ref[1])
        if source == "merge-motion":
            kf = cs.prior
            missing_n = t.missing + 1
        else:
            kf = kalman.correct(cs.prior, kalman.box_measurement(box), Hm, Rm, kcfg).state
        status = TargetStatus.LOST if missing_n > dcfg.max_missing_frames else TargetStatus.MERGED
        if status == TargetStatus.LOST:
            kf = stop(kf)
        if status == TargetStatus.LOST and t.status != TargetStatus.LOST:
            events.append(Event(EventKind.LOST, f"T{t.id} lost (hidden in a merge for {missing_n} frames)", (t.id,)))
        decision = UpdateDecision(False, "merged")
        nt = dataclasses.replace(t, box=box, status=status, kf=kf, memory=None, missing=missing_n,
                                 last_update=str(decision))
        diag = {"rho_y1": cs.rho1, "role": role, "group_size": float(len(css)), "contrast": c.contrast,
                "blob_area_ratio": blob_ratio,
                "components": float(len(c.components)), "missing": float(missing_n)}
        res = TargetResult(t.id, box, status, source, {"meanshift": cs.ms_iters, "levelset": c.iterations},
                           cs.rho1, str(decision), 0.7 if t.id == fg_id else 0.4,
                           c.contour if t.id == fg_id else (), diag,
                           {"prediction": cs.prior.box, "meanshift": cs.box1})
        out[t.id] = (nt, res, events if t.id == fg_id else [])
    _add(timing, "merge", clock)
    mem = GroupMemory(ids, c.memory, union.center, fg_id) if c.box is not None else None
    return out, mem


def _main_blob(phi: np.ndarray, union: BBox, origin: tuple[int, int]) -> np.ndarray | None:
    """Mask of the component of ``phi < 0`` with most pixels inside the group's union box."""
    import cv2

    mask = (phi < 0).astype(np.uint8)
    n, labels = cv2.connectedComponents(mask, connectivity=8)
    if n <= 1:
        return None
    u = union.shifted(-origin[0], -origin[1])
    inside = labels[max(int(u.y), 0):max(int(np.ceil(u.y2)), 0), max(int(u.x), 0):max(int(np.ceil(u.x2)), 0)]
    counts = np.bincount(inside.ravel(), minlength=n)
    counts[0] = 0
    best = int(np.argmax(counts))
    return labels == best if counts[best] > 0 else None
