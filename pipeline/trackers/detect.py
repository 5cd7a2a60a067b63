"""``--tracker detect``: targets found by STDM detection, associated globally every frame.

The system of the ROI feature-matching fusion paper, no initial boxes needed:

1. detect ROIs in the IR frame (``pipeline.stages.detection``; the visible one with
   ``detection.channel = "visible"`` or when there is no IR);
2. predict every track (the shared Kalman stage, constant velocity);
3. for every pair inside the χ² gate: Λ_S from the innovation (eq. 12-13) and Λ_I, the
   affine-invariant correlation of the track's last ROI chip with the detection's
   (``pipeline.stages.roi_match``); cost −ln(Λ_I Λ_S);
4. one global assignment with dummies for missed targets (1 − P_D) and new ones (P_F)
   (``association.associator``: Hungarian, or CHNN);
5. update matched tracks (box and template chip), coast the others; unmatched detections
   start tentative tracks, confirmed after M of N frames; a track missed ``max_misses``
   frames, or more than ``coast_per_hit`` times the detections it has had, or predicted out
   of the frame, is lost; it stays dormant ``relink_frames`` frames (not reported): a
   detection where it could have walked to by then (:func:`_relink`) whose ROI correlates
   with its last one by ``resume_min_correlation`` resumes it at once, and a new track
   confirmed there takes its id (the detector missed the target for a while).

Statuses: ``tentative`` (not yet confirmed; in targets.csv, not in tracks.csv),
``tracking``, ``merged`` (not detected on its own but its prediction lies inside a detected
blob: it coasts inside that blob, and the blob starts no new track), ``occluded-severe``
(confirmed, coasting with no detection near), ``lost`` (the frame it is given up, then
dropped). :func:`detect_init` gives the other trackers their
initial targets from the first frames (``dualtrack track --detect``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipeline.config import PipelineConfig
from pipeline.io.sequence import FramePair
from pipeline.io.sequence import Sequence as FrameSequence
from pipeline.stages import kalman
from pipeline.stages.association import AssociationConfig, get_associator, state_log_likelihoods
from pipeline.stages.detection import (
    Background,
    DetectionConfig,
    Region,
    detect,
    infrared_only,
    to_grey,
)
from pipeline.stages.roi_match import image_likelihood, match_boxes
from pipeline.trackers.base import BackgroundEngine, detector_channel, pick_channel
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
class DetTrack:
    """One track of the detection-driven tracker."""

    id: int
    kf: kalman.GaussianState
    box: BBox
    status: TargetStatus
    born: int  # frame index of its first detection
    hits: int
    misses: int
    template: np.ndarray  # grey frame the template ROI was last seen in
    template_box: BBox


@dataclass(frozen=True)
class DetectState:
    tracks: tuple[DetTrack, ...]
    next_id: int
    channel: str
    background: Background | None = (
        None  # the detector's background estimate (``detection.method = foreground``)
    )
    dormant: tuple[
        tuple[DetTrack, int], ...
    ] = ()  # confirmed tracks given up, with the frame they were lost


def _kcfg(cfg: PipelineConfig) -> kalman.KalmanConfig:
    return _motion_cfg(cfg.kalman, cfg.association)


@functools.lru_cache(maxsize=8)
def _motion_cfg(k: kalman.KalmanConfig, a: AssociationConfig) -> kalman.KalmanConfig:
    """The tracks' constant-velocity model with the association section's noises (made once per
    configuration)."""
    return dataclasses.replace(
        k,
        model="constant_velocity",
        position_noise=a.position_noise,
        size_noise=a.position_noise / 4,
        position_std_px=a.position_std_px,
    )


def _new_track(
    tid: int, r: Region, grey: np.ndarray, frame: int, kcfg: kalman.KalmanConfig
) -> DetTrack:
    return DetTrack(
        tid,
        kalman.init_state(r.box, kcfg),
        r.box,
        TargetStatus.TENTATIVE,
        frame,
        1,
        0,
        grey,
        r.box,
    )


def init(
    frames: FramePair,
    targets: Sequence[InitTarget],
    cfg: PipelineConfig,
    background: Background | None = None,
) -> tuple[DetectState, FrameResult]:
    """Start with no tracks (``targets`` are ignored: the detector finds them); ``background``, the
    detector's (the sequence's, :mod:`pipeline.io.background`), or None to bootstrap it from this
    frame."""
    ch = pick_channel(frames, cfg.detection.channel)
    state = DetectState((), 1, ch, background)
    return step(state, frames, cfg)


def make_engine(cfg: PipelineConfig) -> BackgroundEngine[DetectState]:
    """The detection-driven tracker as an engine; attached to a sequence, its detector uses the
    sequence's background (``detection.background_init = "sequence"``)."""
    return BackgroundEngine(
        "detect", init, step, cfg, detector_channel, detection=detection_settings
    )


def pair_costs(
    tracks: Sequence[DetTrack],
    priors: Sequence[kalman.GaussianState],
    regions: Sequence[Region],
    grey: np.ndarray,
    cfg: PipelineConfig,
    timing: dict[str, float],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cost N x M, Λ_I N x M (NaN outside the gate), γ N x M) of every track/detection pair."""
    a = cfg.association
    rm = cfg.roi_match
    kcfg = _kcfg(cfg)
    Hm, Rm = kalman.measurement_model(kcfg)
    n, m = len(tracks), len(regions)
    cost = np.full((n, m), np.inf)
    lam_i = np.full((n, m), np.nan)
    gam = np.full((n, m), np.inf)
    if n == 0 or m == 0:
        return cost, lam_i, gam
    t0 = time.perf_counter()
    z = np.array([r.centroid for r in regions])
    img_s = 0.0
    for i, (t, prior) in enumerate(zip(tracks, priors, strict=True)):
        S = (Hm @ prior.P @ Hm.T + Rm)[:2, :2]
        ll, g = state_log_likelihoods(z, prior.x[:2], S)  # every detection at once
        gam[i] = g
        for j in np.flatnonzero(g <= a.gate_chi2):
            c = -ll[j] if a.use_state else 0.0
            if a.use_image:
                ti = time.perf_counter()
                rho = match_boxes(
                    t.template, t.template_box.as_tuple(), grey, regions[j].box.as_tuple(), rm
                ).correlation
                img_s += time.perf_counter() - ti
                lam_i[i, j] = rho
                c -= math.log(image_likelihood(rho, rm))
            cost[i, j] = c
    timing["roi_match"] = timing.get("roi_match", 0.0) + img_s
    timing["gating"] = timing.get("gating", 0.0) + time.perf_counter() - t0 - img_s
    return cost, lam_i, gam


@functools.lru_cache(maxsize=8)
def _detection_cfg(dcfg: DetectionConfig, a: AssociationConfig) -> DetectionConfig:
    """The detection settings the tracker runs with: touching regions are split only on request
    (``association.split_touching``), the visible channel's regions only looked for on request
    (``association.use_visible_regions``); made once per configuration, not every frame."""
    if not a.split_touching:
        dcfg = dataclasses.replace(dcfg, split_core_fraction=0.0)
    return dcfg if a.use_visible_regions else infrared_only(dcfg)


def detection_settings(cfg: PipelineConfig) -> DetectionConfig:
    """What :func:`step`'s detector runs with (the engine's sequence background follows it)."""
    return _detection_cfg(cfg.detection, cfg.association)


def step(
    state: DetectState, frames: FramePair, cfg: PipelineConfig
) -> tuple[DetectState, FrameResult]:
    """One frame: detect, predict, associate, update, manage tracks."""
    a = cfg.association
    kcfg = _kcfg(cfg)
    F, Q = kalman.motion_model(kcfg)
    Hm, Rm = kalman.measurement_model(kcfg)
    timing: dict[str, float] = {}
    t0 = time.perf_counter()
    image = getattr(frames, state.channel)
    grey = to_grey(image)
    H, W = grey.shape
    found = detect(
        grey,
        detection_settings(cfg),
        state.background,
        frames.visible if state.channel == "infrared" else None,
    )
    regions = [r for r in found.regions if r.perimeter_px >= a.min_perimeter_px]
    t1 = time.perf_counter()
    timing["detection"] = t1 - t0
    priors = [kalman.predict(t.kf, F, Q) for t in state.tracks]
    # a detection holding the predicted centres of two or more confirmed targets is their merged
    # blob: it measures none of them (they coast inside it) and starts no track
    inside = [
        [
            i
            for i, (t, p) in enumerate(zip(state.tracks, priors, strict=True))
            if t.status != TargetStatus.TENTATIVE and _contains(r.box, p.x[:2])
        ]
        for r in regions
    ]
    group = {j for j, members in enumerate(inside) if len(members) >= 2}
    cost, lam_i, gam = pair_costs(state.tracks, priors, regions, grey, cfg, timing)
    if group:
        cost[:, sorted(group)] = np.inf
    t2 = time.perf_counter()
    miss = np.full(len(state.tracks), -math.log(1.0 - a.detection_probability))
    new = np.full(len(regions), -math.log(a.false_alarm_probability))
    assignment = get_associator(a.associator)(np.where(np.isfinite(cost), cost, 1e9), miss, new)
    timing["association"] = time.perf_counter() - t2
    matched = dict(assignment.pairs)

    events: list[Event] = []
    results: list[TargetResult] = []
    tracks: list[DetTrack] = []
    dormant = tuple(d for d in state.dormant if frames.index - d[1] <= a.relink_frames)
    for i, (t, prior) in enumerate(zip(state.tracks, priors, strict=True)):
        j = matched.get(i)
        age = frames.index - t.born + 1
        if j is not None:
            r = regions[j]
            upd = kalman.correct(prior, kalman.box_measurement(r.box), Hm, Rm, kcfg)
            hits, misses = t.hits + 1, 0
            status = t.status
            if status == TargetStatus.TENTATIVE and hits >= a.confirm_hits:
                status = TargetStatus.TRACKING
                old = _relink(r.box, dormant, frames.index, a.relink_frames)
                if old is not None:
                    dormant = tuple(d for d in dormant if d[0].id != old.id)
                    events.append(
                        Event(
                            EventKind.REACQUIRED,
                            f"T{old.id} found again ({frames.index - t.born + 1} "
                            f"frames after a new track started on it)",
                            (old.id,),
                        )
                    )
                    t = dataclasses.replace(t, id=old.id)
                else:
                    events.append(
                        Event(
                            EventKind.CONFIRMED,
                            f"T{t.id} confirmed ({hits} detections in {age} frames)",
                            (t.id,),
                        )
                    )
            elif status in (TargetStatus.OCCLUDED_SEVERE, TargetStatus.MERGED):
                events.append(
                    Event(
                        EventKind.SPLIT
                        if status == TargetStatus.MERGED
                        else EventKind.OCCLUSION_END,
                        f"T{t.id} detected again on its own",
                        (t.id,),
                    )
                )
                status = TargetStatus.TRACKING
            box = r.box
            nt = dataclasses.replace(
                t,
                kf=upd.state,
                box=box,
                status=status,
                hits=hits,
                misses=misses,
                template=grey,
                template_box=r.box,
            )
            rho = lam_i[i, j]
            diag = {
                "gamma": float(gam[i, j]),
                "lambda_i": float(rho) if np.isfinite(rho) else float("nan"),
                "cost": float(cost[i, j]),
                "detections": float(len(regions)),
            }
            source = "detection"
        elif (
            t.status != TargetStatus.TENTATIVE
            and (k := _blob_containing(prior, regions)) is not None
        ):
            # not detected on its own but inside a detected blob: merged with another target; coast
            # inside it
            r = regions[k]
            c = _inside(prior.x[:2], (float(prior.x[2]), float(prior.x[3])), r.box)
            box = BBox.from_center(
                c[0], c[1], max(float(prior.x[2]), 1.0), max(float(prior.x[3]), 1.0)
            )
            hits, misses = t.hits, t.misses + 1
            status = TargetStatus.MERGED
            if t.status != TargetStatus.MERGED:
                events.append(
                    Event(
                        EventKind.MERGE,
                        f"T{t.id} merged into the blob at "
                        f"({r.centroid[0]:.0f},{r.centroid[1]:.0f})",
                        (t.id,),
                    )
                )
            if misses > a.max_merged_frames:
                status = TargetStatus.LOST
                events.append(
                    Event(
                        EventKind.LOST,
                        f"T{t.id} lost ({misses} frames inside a merged blob)",
                        (t.id,),
                    )
                )
            nt = dataclasses.replace(t, kf=prior, box=box, status=status, hits=hits, misses=misses)
            diag = {"detections": float(len(regions)), "missing": float(misses)}
            source = "kalman-in-blob"
            rho = float("nan")
        else:
            hits, misses = t.hits, t.misses + 1
            box = prior.box
            status = t.status
            if status == TargetStatus.TENTATIVE:
                if age >= a.confirm_window:  # failed M of N: dropped without ever being reported
                    continue
            elif (
                misses > min(a.max_misses, a.coast_per_hit * hits)
                or box.clip(W, H).area < 0.25 * box.area
            ):
                status = TargetStatus.LOST
                why = (
                    "left the frame"
                    if box.clip(W, H).area < 0.25 * box.area
                    else f"{misses} frames without a detection"
                )
                events.append(Event(EventKind.LOST, f"T{t.id} lost ({why})", (t.id,)))
            elif status in (TargetStatus.TRACKING, TargetStatus.MERGED):
                status = TargetStatus.OCCLUDED_SEVERE
                events.append(
                    Event(EventKind.OCCLUSION_START, f"T{t.id} not detected (coasting)", (t.id,))
                )
            nt = dataclasses.replace(t, kf=prior, box=box, status=status, hits=hits, misses=misses)
            diag = {"detections": float(len(regions)), "missing": float(misses)}
            source = "kalman"
            rho = float("nan")
        if status == TargetStatus.TENTATIVE and age >= a.confirm_window and hits < a.confirm_hits:
            continue
        conf = {
            TargetStatus.TRACKING: 1.0,
            TargetStatus.OCCLUDED_SEVERE: 0.3,
            TargetStatus.TENTATIVE: 0.2,
        }.get(status, 0.0)
        results.append(
            TargetResult(
                t.id,
                box,
                status,
                source,
                {},
                float(rho) if np.isfinite(rho) else float("nan"),
                "none",
                conf,
                (),
                diag,
                {"prediction": prior.box},
            )
        )
        if status != TargetStatus.LOST:
            tracks.append(nt)
        elif a.relink_frames > 0:
            dormant += ((nt, frames.index),)
    next_id = state.next_id
    for j in assignment.unmatched_detections:
        r = regions[j]
        if j in group or any(
            t.status != TargetStatus.TENTATIVE and _contains(r.box, p.x[:2])
            for t, p in zip(state.tracks, priors, strict=True)
        ):
            continue  # a blob around a known target (merged targets): not a new one
        old = (
            _relink(r.box, dormant, frames.index, a.relink_frames)
            if a.resume_min_correlation <= 1
            else None
        )
        if old is not None:
            rho = match_boxes(
                old.template, old.template_box.as_tuple(), grey, r.box.as_tuple(), cfg.roi_match
            ).correlation
            if not (np.isfinite(rho) and rho >= a.resume_min_correlation):
                old = None
        # a dormant track detected again, looking as it did: it resumes at once, with its id
        if old is not None:
            dormant = tuple(d for d in dormant if d[0].id != old.id)
            t = dataclasses.replace(
                _new_track(old.id, r, grey, frames.index, kcfg),
                status=TargetStatus.TRACKING,
                hits=a.confirm_hits,
            )
            events.append(Event(EventKind.REACQUIRED, f"T{old.id} detected again", (old.id,)))
        else:
            t = _new_track(next_id, r, grey, frames.index, kcfg)
            events.append(
                Event(
                    EventKind.BIRTH,
                    f"T{next_id} born at ({r.centroid[0]:.0f},{r.centroid[1]:.0f})",
                    (next_id,),
                )
            )
            next_id += 1
            if a.confirm_hits <= 1:
                t = dataclasses.replace(t, status=TargetStatus.TRACKING)
        tracks.append(t)
        results.append(
            TargetResult(
                t.id,
                r.box,
                t.status,
                "detection",
                {},
                float("nan"),
                "none",
                0.2 if t.status == TargetStatus.TENTATIVE else 1.0,
                (),
                {"detections": float(len(regions))},
                {},
            )
        )
    timing["detect_tracker"] = time.perf_counter() - t0
    res = FrameResult(
        frames.index, tuple(sorted(results, key=lambda r: r.id)), tuple(events), timing
    )
    return DetectState(tuple(tracks), next_id, state.channel, found.background, dormant), res


def _relink(
    box: BBox, dormant: Sequence[tuple[DetTrack, int]], frame: int, max_frames: int
) -> DetTrack | None:
    """The dormant track that a detection (or a newly confirmed track) at ``frame`` on ``box``
    continues, or None.

    A dormant track, last detected ``gap`` frames ago at centre ``c0`` with velocity ``v`` (its
    Kalman state), is a candidate when it was lost at most ``max_frames`` frames ago, its
    height is within a factor 2 of ``box``'s, and ``box``'s centre lies within
    ``max(w, h) + (|v| + 1 px) * gap`` of ``c0 + v * min(gap, 10)`` (the velocity is trusted
    for 10 frames at most: targets stop and turn). The nearest candidate, in distance over
    that radius, is taken.
    """
    best, best_d = None, 1.0
    cx, cy = box.center
    for d, lost in dormant:
        if frame - lost > max_frames or not 0.5 <= box.h / max(d.template_box.h, 1.0) <= 2.0:
            continue
        gap = frame - (lost - d.misses)
        vx, vy = float(d.kf.x[4]), float(d.kf.x[5])
        px, py = d.template_box.center
        k = min(gap, 10)
        radius = max(d.template_box.w, d.template_box.h) + (math.hypot(vx, vy) + 1.0) * gap
        dist = math.hypot(cx - (px + vx * k), cy - (py + vy * k)) / radius
        if dist < best_d:
            best, best_d = d, dist
    return best


def _contains(box: BBox, c: np.ndarray) -> bool:
    return box.x <= float(c[0]) <= box.x2 and box.y <= float(c[1]) <= box.y2


def _blob_containing(prior: kalman.GaussianState, regions: Sequence[Region]) -> int | None:
    """Index of the detected region whose box holds the predicted centre (None if none does)."""
    for k, r in enumerate(regions):
        if _contains(r.box, prior.x[:2]):
            return k
    return None


def _inside(c: np.ndarray, size: tuple[float, float], blob: BBox) -> tuple[float, float]:
    """Centre ``c`` moved so that a box of ``size`` lies inside ``blob`` (centred where it
    cannot)."""
    out = []
    for v, sz, lo, hi in (
        (float(c[0]), size[0], blob.x, blob.x2),
        (float(c[1]), size[1], blob.y, blob.y2),
    ):
        a, b = lo + sz / 2, hi - sz / 2
        out.append((lo + hi) / 2 if a > b else min(max(v, a), b))
    return out[0], out[1]


def detect_init(
    seq: FrameSequence, cfg: PipelineConfig, frames_to_scan: int = 5
) -> list[InitTarget]:
    """Initial targets for another tracker: run the detection-driven tracker over the first
    frames and take the tracks confirmed by then that were detected in frame 1, at their
    frame-1 boxes, with ids 1..N left to right (an InputError when there is none)."""
    from pipeline.errors import InputError

    engine = make_engine(cfg)
    engine.attach(seq)
    n = min(frames_to_scan, seq.n_frames)
    first: dict[int, BBox] = {}
    res = None
    for fp in seq.frames():
        if fp.index > n:
            break
        res = engine.start(fp, []) if fp.index == 1 else engine.step(fp)
        if fp.index == 1:
            first = {r.id: r.box for r in res.targets}
    assert res is not None
    found = [
        first[r.id] for r in res.targets if r.status == TargetStatus.TRACKING and r.id in first
    ]
    if not found:
        raise InputError(
            f"--detect found no target in frame 1 confirmed within {n} frames of {seq.path}; "
            "pass --init x,y,w,h or tune the [detection] section"
        )
    return [InitTarget(k + 1, b) for k, b in enumerate(sorted(found, key=lambda b: (b.x, b.y)))]
