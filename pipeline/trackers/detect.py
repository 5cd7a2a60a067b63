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

On the frames where the sequence's background does not hold (a moving camera:
:attr:`pipeline.stages.detection.Background.holds`), unmatched regions start no new tracks
(they are the scene's own texture as often as targets); tracks already there go on, and a
dormant one still resumes; the run says so in one line and in ``summary.json`` (``camera``).

Statuses: ``tentative`` (not yet confirmed; in targets.csv, not in tracks.csv),
``tracking``, ``merged`` (not detected on its own but its prediction lies inside a detected
blob: it is measured where its template matches inside the blob, the blob's members placed
together by :func:`pipeline.stages.blob.place_members`, source ``blob-match``; or, found
nowhere well, it coasts inside the blob, source ``kalman-in-blob``; the blob starts no new
track), ``occluded-severe``
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
from typing import ClassVar

import numpy as np

from pipeline.io.sequence import FramePair
from pipeline.io.sequence import Sequence as FrameSequence
from pipeline.stages import blob, kalman
from pipeline.stages.association import (
    AssociationConfig,
    Associator,
    hungarian,
    state_log_likelihoods,
)
from pipeline.stages.chnn import chnn_associator
from pipeline.stages.detection import (
    Background,
    DetectionConfig,
    Region,
    detect,
    infrared_only,
    to_grey,
)
from pipeline.stages.roi_match import image_likelihood, match_boxes
from pipeline.tracker_config import DetectConfig
from pipeline.trackers.base import CoreEngine, pick_channel, preferred_channel
from pipeline.trackers.lifecycle import born, coast_ends, transition
from pipeline.types import (
    BBox,
    Event,
    FrameResult,
    InitTarget,
    TargetResult,
    TargetStatus,
)

ASSOCIATORS: dict[str, Associator] = {"hungarian": hungarian, "chnn": chnn_associator}
"""The global assignment of ``association.associator``."""


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
    """The tracks, the next id, the detector's channel and background estimate
    (``detection.method = foreground``), and the confirmed tracks given up with the frame they
    were lost (dormant)."""

    tracks: tuple[DetTrack, ...]
    next_id: int
    channel: str
    background: Background | None = None
    dormant: tuple[tuple[DetTrack, int], ...] = ()


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


@functools.lru_cache(maxsize=8)
def _detection_cfg(dcfg: DetectionConfig, a: AssociationConfig) -> DetectionConfig:
    """The detection settings the tracker runs with: the visible channel's regions only looked
    for on request (``association.use_visible_regions``); made once per configuration, not every
    frame."""
    return dcfg if a.use_visible_regions else infrared_only(dcfg)


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


@dataclass(frozen=True)
class FrameMatch:
    """One frame's detections and their assignment to the tracks: the regions, every track's
    prediction, the regions that hold two or more confirmed tracks' predictions (merged blobs),
    the pair costs, Lambda_I and gamma, and the assignment ``{track: region}``."""

    grey: np.ndarray
    regions: list[Region]
    priors: list[kalman.GaussianState]
    group: set[int]
    cost: np.ndarray
    lam_i: np.ndarray
    gam: np.ndarray
    matched: dict[int, int]
    unmatched: tuple[int, ...]
    background: Background | None
    placed: dict[int, blob.Placement] = dataclasses.field(default_factory=dict)


class _Ledger:
    """What one frame's track management accumulates: events, results, surviving tracks and the
    dormant ones."""

    def __init__(self, dormant: tuple[tuple[DetTrack, int], ...]):
        self.events: list[Event] = []
        self.results: list[TargetResult] = []
        self.tracks: list[DetTrack] = []
        self.dormant = dormant

    def wake(self, tid: int) -> None:
        """Track ``tid`` leaves the dormant ones (it resumed)."""
        self.dormant = tuple(d for d in self.dormant if d[0].id != tid)


@dataclass(frozen=True)
class DetectAndAssociate:
    """The detection-driven tracker: one pure core over its ``detect`` section.

    Parameters
    ----------
    cfg : DetectConfig
        The detector (``detection``), the ROI correlation (``roi_match``), the association and
        track management (``association``) and the tracks' motion (``kalman``).
    """

    cfg: DetectConfig
    on_moving_camera: ClassVar[str] = "they start no new tracks there"
    """What the tracker does where a moving camera's frames defeat the background (the end of
    the run's one line about it)."""

    @property
    def kalman(self) -> kalman.KalmanConfig:
        """The tracks' constant-velocity model."""
        return _motion_cfg(self.cfg.kalman, self.cfg.association)

    @property
    def detection(self) -> DetectionConfig:
        """What the detector runs with (the engine's sequence background follows it)."""
        return _detection_cfg(self.cfg.detection, self.cfg.association)

    def detector_channel(self, channels: tuple[str, ...]) -> str:
        """The channel the detector runs on: ``detection.channel`` if present, else the other."""
        return preferred_channel(channels, self.cfg.detection.channel)

    def init(
        self,
        frames: FramePair,
        targets: Sequence[InitTarget],
        background: Background | None = None,
    ) -> tuple[DetectState, FrameResult]:
        """Start with no tracks (``targets`` are ignored: the detector finds them);
        ``background``, the detector's (the sequence's, :mod:`pipeline.io.background`), or None
        to bootstrap it from this frame."""
        ch = pick_channel(frames, self.cfg.detection.channel)
        return self.step(DetectState((), 1, ch, background), frames)

    def step(self, state: DetectState, frames: FramePair) -> tuple[DetectState, FrameResult]:
        """One frame: detect, predict, associate, update, manage tracks."""
        timing: dict[str, float] = {}
        t0 = time.perf_counter()
        fm = self.match(state, frames, timing)
        a = self.cfg.association
        ledger = _Ledger(tuple(d for d in state.dormant if frames.index - d[1] <= a.relink_frames))
        for i, (t, prior) in enumerate(zip(state.tracks, fm.priors, strict=True)):
            self._manage(i, t, prior, fm, frames.index, ledger)
        next_id = self._births(state, fm, frames.index, ledger)
        timing["detect_tracker"] = time.perf_counter() - t0
        results = tuple(sorted(ledger.results, key=lambda r: r.id))
        res = FrameResult(frames.index, results, tuple(ledger.events), timing)
        new = DetectState(
            tuple(ledger.tracks), next_id, state.channel, fm.background, ledger.dormant
        )
        return new, res

    def match(self, state: DetectState, frames: FramePair, timing: dict[str, float]) -> FrameMatch:
        """Detect, predict every track, and assign detections to tracks globally; a detection
        holding the predicted centres of two or more confirmed targets is their merged blob: it
        measures none of them (they coast inside it) and starts no track."""
        a = self.cfg.association
        F, Q = kalman.motion_model(self.kalman)
        t0 = time.perf_counter()
        grey = to_grey(getattr(frames, state.channel))
        vis = frames.visible if state.channel == "infrared" else None
        found = detect(grey, self.detection, state.background, vis)
        regions = [r for r in found.regions if r.perimeter_px >= a.min_perimeter_px]
        timing["detection"] = time.perf_counter() - t0
        priors = [kalman.predict(t.kf, F, Q) for t in state.tracks]
        inside = {
            j: [
                i
                for i, (t, p) in enumerate(zip(state.tracks, priors, strict=True))
                if t.status != TargetStatus.TENTATIVE
                and r.box.contains(float(p.x[0]), float(p.x[1]))
            ]
            for j, r in enumerate(regions)
        }
        blobs = {j: ids for j, ids in inside.items() if len(ids) >= 2}
        group = set(blobs)
        cost, lam_i, gam = self.pair_costs(state.tracks, priors, regions, grey, timing)
        if group:
            cost[:, sorted(group)] = np.inf
        t2 = time.perf_counter()
        miss = np.full(len(state.tracks), -math.log(1.0 - a.detection_probability))
        new = np.full(len(regions), -math.log(a.false_alarm_probability))
        finite = np.where(np.isfinite(cost), cost, 1e9)
        assignment = ASSOCIATORS[a.associator](finite, miss, new)
        timing["association"] = time.perf_counter() - t2
        t3 = time.perf_counter()
        placed = self.place(state.tracks, priors, regions, blobs, grey)
        timing["blobs"] = time.perf_counter() - t3
        return FrameMatch(
            grey,
            regions,
            priors,
            group,
            cost,
            lam_i,
            gam,
            dict(assignment.pairs),
            tuple(assignment.unmatched_detections),
            found.background,
            placed,
        )

    def place(
        self,
        tracks: Sequence[DetTrack],
        priors: Sequence[kalman.GaussianState],
        regions: Sequence[Region],
        blobs: dict[int, list[int]],
        grey: np.ndarray,
    ) -> dict[int, blob.Placement]:
        """``{track: placement}`` of the confirmed tracks inside the merged blobs (``blobs``:
        region index -> the tracks whose predicted centres it holds), each blob's members placed
        jointly (:func:`pipeline.stages.blob.place_members`); tracks found nowhere well are left
        out."""
        a = self.cfg.association
        if not a.place_in_blobs or not blobs:
            return {}
        out: dict[int, blob.Placement] = {}
        for j, idx in sorted(blobs.items()):
            members: list[blob.Member | None] = []
            for i in idx:
                patch = blob.template_patch(tracks[i].template, tracks[i].template_box)
                members.append(
                    None
                    if patch is None
                    else blob.Member(
                        patch,
                        (float(priors[i].x[0]), float(priors[i].x[1])),
                        self._position_cov(priors[i]),
                        a.blob_reach_fraction,
                    )
                )
            found = blob.place_members(
                grey,
                regions[j].box,
                members,
                gate_chi2=a.gate_chi2,
                min_correlation=a.blob_min_correlation,
                motion_weight=a.blob_motion_weight,
            )
            for i, p in zip(idx, found, strict=True):
                if p is not None and i not in out:
                    out[i] = p
        return out

    def _position_cov(self, prior: kalman.GaussianState) -> np.ndarray:
        """The 2 x 2 covariance of a prediction's centre innovation, px^2 (the gate's)."""
        Hm, Rm = kalman.measurement_model(self.kalman)
        return (Hm @ prior.P @ Hm.T + Rm)[:2, :2]

    def pair_costs(
        self,
        tracks: Sequence[DetTrack],
        priors: Sequence[kalman.GaussianState],
        regions: Sequence[Region],
        grey: np.ndarray,
        timing: dict[str, float],
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(cost N x M, Λ_I N x M (NaN outside the gate), γ N x M) of every track/detection
        pair."""
        a, rm = self.cfg.association, self.cfg.roi_match
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
            S = self._position_cov(prior)
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

    # -------------------------------------------------------------------- track management
    def _manage(
        self,
        i: int,
        t: DetTrack,
        prior: kalman.GaussianState,
        fm: FrameMatch,
        frame: int,
        ledger: _Ledger,
    ) -> None:
        """Track ``i`` after the assignment: updated by its detection, coasting inside a merged
        blob, or coasting (confirmed, lost or dropped); its result and events go to ``ledger``."""
        j = fm.matched.get(i)
        if j is not None:
            nt, diag, rho = self._detected(i, j, t, prior, fm, frame, ledger)
            source = "detection"
        elif (
            t.status != TargetStatus.TENTATIVE
            and (k := _blob_containing(prior, fm.regions)) is not None
        ):
            p = fm.placed.get(i)
            nt, diag, rho, source = (
                self._in_blob(t, prior, fm.regions[k], ledger, p),
                {},
                math.nan if p is None else p.correlation,
                "kalman-in-blob" if p is None else "blob-match",
            )
        else:
            nt = self._coasting(t, prior, fm.grey.shape, frame, ledger)
            if nt is None:  # failed M of N: dropped without ever being reported
                return
            diag, rho, source = {}, math.nan, "kalman"
        if not diag:
            diag = {"detections": float(len(fm.regions)), "missing": float(nt.misses)}
        a = self.cfg.association
        age = frame - t.born + 1
        if (
            nt.status == TargetStatus.TENTATIVE
            and age >= a.confirm_window
            and nt.hits < a.confirm_hits
        ):
            return
        ledger.results.append(_result(nt, prior, source, rho, diag))
        if nt.status != TargetStatus.LOST:
            ledger.tracks.append(nt)
        elif a.relink_frames > 0:
            ledger.dormant += ((nt, frame),)

    def _detected(
        self,
        i: int,
        j: int,
        t: DetTrack,
        prior: kalman.GaussianState,
        fm: FrameMatch,
        frame: int,
        ledger: _Ledger,
    ) -> tuple[DetTrack, dict[str, float], float]:
        """A track updated by detection ``j``: confirmed after M of N (taking a dormant track's
        id where it could be that track), or back from a merge or a coast."""
        a = self.cfg.association
        r = fm.regions[j]
        Hm, Rm = kalman.measurement_model(self.kalman)
        upd = kalman.correct(prior, kalman.box_measurement(r.box), Hm, Rm, self.kalman)
        hits, status = t.hits + 1, t.status
        if status == TargetStatus.TENTATIVE and hits >= a.confirm_hits:
            status = TargetStatus.TRACKING
            t = self._confirmed(t, r, hits, frame, ledger)
        elif status in (TargetStatus.OCCLUDED_SEVERE, TargetStatus.MERGED):
            ledger.events += transition(t.id, status, TargetStatus.TRACKING, "detected on its own")
            status = TargetStatus.TRACKING
        nt = dataclasses.replace(
            t,
            kf=upd.state,
            box=r.box,
            status=status,
            hits=hits,
            misses=0,
            template=fm.grey,
            template_box=r.box,
        )
        rho = fm.lam_i[i, j]
        diag = {
            "gamma": float(fm.gam[i, j]),
            "lambda_i": float(rho) if np.isfinite(rho) else float("nan"),
            "cost": float(fm.cost[i, j]),
            "detections": float(len(fm.regions)),
        }
        return nt, diag, rho

    def _confirmed(
        self, t: DetTrack, r: Region, hits: int, frame: int, ledger: _Ledger
    ) -> DetTrack:
        """A tentative track just confirmed: it takes the id of a dormant track that could have
        walked to ``r`` (:func:`_relink`), or is announced as a new target."""
        age = frame - t.born + 1
        old = _relink(r.box, ledger.dormant, frame, self.cfg.association.relink_frames)
        if old is None:
            why = f"{hits} detections in {age} frames"
            ledger.events += transition(t.id, t.status, TargetStatus.TRACKING, why)
            return t
        ledger.wake(old.id)
        why = f"found again {age} frames after a new track started on it"
        ledger.events += transition(old.id, old.status, TargetStatus.TRACKING, why)
        return dataclasses.replace(t, id=old.id)

    def _in_blob(
        self,
        t: DetTrack,
        prior: kalman.GaussianState,
        r: Region,
        ledger: _Ledger,
        placed: blob.Placement | None = None,
    ) -> DetTrack:
        """A confirmed track not detected on its own but inside a detected blob: merged with
        another target, it is measured where its template placed it in the blob (``placed``,
        its template not learning), else coasts inside the blob (lost after
        ``max_merged_frames``)."""
        kf = prior
        if placed is not None:
            Hm, Rm = kalman.measurement_model(self.kalman)
            z = kalman.box_measurement(placed.box)
            kf = kalman.correct(prior, z, Hm, Rm, self.kalman).state
            box = placed.box
        else:
            c = _inside(prior.x[:2], (float(prior.x[2]), float(prior.x[3])), r.box)
            w, h = max(float(prior.x[2]), 1.0), max(float(prior.x[3]), 1.0)
            box = BBox.from_center(c[0], c[1], w, h)
        misses = t.misses + 1
        status = TargetStatus.MERGED
        if t.status != TargetStatus.MERGED:
            at = f"({r.centroid[0]:.0f},{r.centroid[1]:.0f})"
            ledger.events += transition(t.id, t.status, status, f"into the blob at {at}")
        if misses > self.cfg.association.max_merged_frames:
            why = f"{misses} frames inside a merged blob"
            ledger.events += transition(t.id, status, TargetStatus.LOST, why)
            status = TargetStatus.LOST
        return dataclasses.replace(t, kf=kf, box=box, status=status, misses=misses)

    def _coasting(
        self,
        t: DetTrack,
        prior: kalman.GaussianState,
        shape: tuple[int, int],
        frame: int,
        ledger: _Ledger,
    ) -> DetTrack | None:
        """A track without a detection: a tentative one that failed M of N is dropped (None); a
        confirmed one coasts, and is lost after too many misses or out of the frame."""
        a = self.cfg.association
        misses = t.misses + 1
        box = prior.box
        status = t.status
        if status == TargetStatus.TENTATIVE:
            if frame - t.born + 1 >= a.confirm_window:
                return None
        elif why := coast_ends(box, shape, misses, min(a.max_misses, a.coast_per_hit * t.hits)):
            ledger.events += transition(t.id, status, TargetStatus.LOST, why)
            status = TargetStatus.LOST
        elif status in (TargetStatus.TRACKING, TargetStatus.MERGED):
            why = "not detected, coasting"
            ledger.events += transition(t.id, status, TargetStatus.OCCLUDED_SEVERE, why)
            status = TargetStatus.OCCLUDED_SEVERE
        return dataclasses.replace(t, kf=prior, box=box, status=status, misses=misses)

    def _births(self, state: DetectState, fm: FrameMatch, frame: int, ledger: _Ledger) -> int:
        """New tentative tracks on the unmatched detections that are not a blob around a known
        target; a dormant track detected again, looking as it did, resumes at once with its id.
        Returns the next free id."""
        a = self.cfg.association
        next_id = state.next_id
        holds = fm.background is None or fm.background.holds
        for j in fm.unmatched:
            r = fm.regions[j]
            if j in fm.group or any(
                t.status != TargetStatus.TENTATIVE and r.box.contains(float(p.x[0]), float(p.x[1]))
                for t, p in zip(state.tracks, fm.priors, strict=True)
            ):
                continue  # a blob around a known target (merged targets): not a new one
            t = self._resumed(r, fm.grey, frame, ledger)
            if t is None and not holds:
                continue  # a moving camera: the region is as likely the scene's texture
            if t is None:
                t = _new_track(next_id, r, fm.grey, frame, self.kalman)
                at = f"({r.centroid[0]:.0f},{r.centroid[1]:.0f})"
                ledger.events += born(next_id, f"detected at {at}")
                next_id += 1
                if a.confirm_hits <= 1:
                    t = dataclasses.replace(t, status=TargetStatus.TRACKING)
            ledger.tracks.append(t)
            conf = 0.2 if t.status == TargetStatus.TENTATIVE else 1.0
            detections = {"detections": float(len(fm.regions))}
            ledger.results.append(
                TargetResult(
                    t.id,
                    r.box,
                    t.status,
                    "detection",
                    {},
                    float("nan"),
                    "none",
                    conf,
                    (),
                    detections,
                    {},
                )
            )
        return next_id

    def _resumed(
        self, r: Region, grey: np.ndarray, frame: int, ledger: _Ledger
    ) -> DetTrack | None:
        """The dormant track that detection ``r`` continues, resumed (confirmed, with its id),
        when its ROI correlates with the track's last one by ``resume_min_correlation``."""
        a = self.cfg.association
        if a.resume_min_correlation > 1:
            return None
        old = _relink(r.box, ledger.dormant, frame, a.relink_frames)
        if old is None:
            return None
        rho = match_boxes(
            old.template, old.template_box.as_tuple(), grey, r.box.as_tuple(), self.cfg.roi_match
        ).correlation
        if not (np.isfinite(rho) and rho >= a.resume_min_correlation):
            return None
        ledger.wake(old.id)
        why = "detected again, looking as it did"
        ledger.events += transition(old.id, old.status, TargetStatus.TRACKING, why)
        t = _new_track(old.id, r, grey, frame, self.kalman)
        return dataclasses.replace(t, status=TargetStatus.TRACKING, hits=a.confirm_hits)


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


def _blob_containing(prior: kalman.GaussianState, regions: Sequence[Region]) -> int | None:
    """Index of the detected region whose box holds the predicted centre (None if none does)."""
    for k, r in enumerate(regions):
        if r.box.contains(float(prior.x[0]), float(prior.x[1])):
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


def make_engine(cfg: DetectConfig) -> CoreEngine[DetectState]:
    """The detection-driven tracker as an engine; attached to a sequence, its detector uses the
    sequence's background (``detection.background_init = "sequence"``)."""
    return CoreEngine("detect", DetectAndAssociate(cfg))


def _result(
    nt: DetTrack, prior: kalman.GaussianState, source: str, rho: float, diag: dict[str, float]
) -> TargetResult:
    """Track ``nt``'s row of the frame: its box and status, the measurement's ``source`` and
    colour match ``rho``, a confidence by status, the prediction as its candidate box."""
    conf = {
        TargetStatus.TRACKING: 1.0,
        TargetStatus.OCCLUDED_SEVERE: 0.3,
        TargetStatus.TENTATIVE: 0.2,
    }.get(nt.status, 0.0)
    return TargetResult(
        nt.id,
        nt.box,
        nt.status,
        source,
        {},
        float(rho) if np.isfinite(rho) else float("nan"),
        "none",
        conf,
        (),
        diag,
        {"prediction": prior.box},
    )


def detect_init(
    seq: FrameSequence, cfg: DetectConfig, frames_to_scan: int = 5
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
            "pass --init x,y,w,h or tune the [detect.detection] section"
        )
    return [InitTarget(k + 1, b) for k, b in enumerate(sorted(found, key=lambda b: (b.x, b.y)))]
