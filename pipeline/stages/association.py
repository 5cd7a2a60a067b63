"""Global association of detections to tracks (the fusion paper's eq. 1-4 and 12-13).

Each (detection m, track n) pair has a likelihood Λ = Λ_I · Λ_S: the image term from ROI
correlation (``pipeline.stages.roi_match``) and the state term, the Gaussian innovation
likelihood of the detection's position under the track's Kalman prediction (eq. 12-13)::

    Λ_S = exp(-γ/2) / (2π √|S|),  γ = dᵀ S⁻¹ d,  d = z_m − ẑ_n

A detection may also be a new target or a false alarm (the dummy track column, probability
P_F) and a track may have no detection this frame (the dummy row, 1 − P_D). The
assignment minimizing Σ −ln Λ over all of that is one Hungarian problem on the padded
square matrix :func:`padded_cost` builds; :func:`hungarian` solves it. Pairs outside the
gate (γ above a χ² quantile) are impossible.

The associator is a swappable part: anything with the signature of :func:`hungarian`
(cost matrix, miss costs per track, new costs per detection -> :class:`Assignment`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from pipeline.params import Section, param

IMPOSSIBLE = 1e9


@dataclass(frozen=True)
class AssociationConfig(Section):
    """Association of detections to tracks.

    Parameters
    ----------
    detection_probability : float
        P_D: a track's target is detected in a frame, in (0, 1); default 0.9.
    false_alarm_probability : float
        P_F: the likelihood given to a detection that starts a track or is clutter, > 0;
        default 1e-4 (compared with Λ_S of a good match, ~1e-3 for a few px of error).
    gate_chi2 : float
        Pairs whose Mahalanobis γ exceeds this are impossible, > 0; default 13.8 (χ² with
        2 degrees of freedom at 99.9 %).
    use_image : bool
        Multiply Λ_S by the image term Λ_I (fused); False: state only; default True.
    use_state : bool
        Use Λ_S (False: image only, still gated); default True.
    associator : str
        ``hungarian`` (default: the optimum of the global assignment, exactly) or ``chnn``
        (the competitive Hopfield network of the CHNN papers, an energy descent that reaches
        the optimum on most frames and is the papers' method).
    confirm_hits : int
        A new track is confirmed after this many detections (M of M-of-N), >= 1; default 3.
    confirm_window : int
        ... within its first this many frames (N), >= 1 and >= ``confirm_hits``; default 5.
    max_misses : int
        A confirmed track is lost after this many frames without a detection, >= 1; default 1:
        a detected target's coasting box (its constant-velocity prediction) lies off the target
        by IoU 0.5 far more often than on it, and a lost track is not gone for good (it stays
        dormant, ``relink_frames``); raise it where targets move steadily behind occluders.
    coast_per_hit : float
        ... or after more frames without one than this many times the detections it has had,
        >= 0; default 0.5: a track confirmed on a few detections of a passing shadow or a ghost
        coasts a few frames, not ``max_misses``.
    max_merged_frames : int
        ... or after this many frames merged into another target's blob, >= 1; default 90.
    min_perimeter_px : float
        The detection-driven tracker uses only the detected regions whose boundary is at
        least this long, px, >= 0; default 40: the detector's smaller regions (distant people,
        but also a target's warm parts) give boxes too small for the target they lie on and
        pull its track onto a part; 0 uses every region the detector keeps.
    use_visible_regions : bool
        Whether the detection-driven tracker also uses the regions the detector finds in the
        visible channel with weak IR support (``detection.visible_support_k``); default
        False: they find more of the targets, but also start tracks on the visible
        channel's false foreground, which costs more (MOTA) than the targets gained.
    relink_frames : int
        A lost track stays dormant this many frames, >= 0; default 60: a detection near where
        a dormant one would be by then resumes it (``resume_min_correlation``), and a new
        track confirmed there takes its identity (the detector missed the target for a
        while); 0 disables.
    resume_min_correlation : float
        A detection not taken by a live track, within reach of a dormant one (as above) and
        whose ROI correlates with the dormant track's last ROI by at least this much (Λ_I's
        correlation), resumes the dormant track at once, >= -1; default 0.8. Above 1: never
        at once, only when a new track is confirmed there (lower values resume sooner and on
        look-alikes too).
    position_noise : float
        Process noise of the tracks' constant-velocity Kalman filter (white acceleration,
        (px/frame^2)^2), > 0; default 0.5: detected targets turn and stop.
    position_std_px : float
        Measurement noise of a detection's centre, px, > 0; default 2.
    place_in_blobs : bool
        Whether the members of a merged blob (a region holding two or more confirmed tracks'
        predictions) are placed inside it by their templates and motion
        (:func:`pipeline.stages.blob.place_members`) and measured there, instead of all
        coasting on their predictions; default True. False: every member coasts inside its
        blob (the paper's system).
    blob_min_correlation : float
        A member is placed only where its template correlates above this (normalised
        correlation coefficient), in [-1, 1]; default 0.5. Lower places more members, also on
        the parts of the blob that only resemble them.
    blob_reach_fraction : float
        A member is placed at most this share of its template's width (across) and height
        (up and down) from its prediction, > 0; default 0.25: the placement refines the
        motion's position, it does not move a member onto another target.
    blob_motion_weight : float
        A place's worth is its correlation above ``blob_min_correlation`` minus this times its
        squared Mahalanobis distance from the prediction, >= 0; default 0.036 (at the gate's
        edge, 0.5 of correlation): a far place must match better than a near one.
    """

    section = "association"

    detection_probability: float = param(0.9, gt=0, lt=1)
    false_alarm_probability: float = param(1e-4, gt=0)
    gate_chi2: float = param(13.8, gt=0)
    use_image: bool = True
    use_state: bool = True
    associator: str = param("hungarian", choices=("hungarian", "chnn"))
    confirm_hits: int = param(3, ge=1)
    confirm_window: int = param(5, ge=1)
    max_misses: int = param(1, ge=1)
    coast_per_hit: float = param(0.5, ge=0)
    max_merged_frames: int = param(90, ge=1)
    relink_frames: int = param(60, ge=0)
    resume_min_correlation: float = param(0.8, ge=-1)
    min_perimeter_px: float = param(40.0, ge=0)
    use_visible_regions: bool = False
    position_noise: float = param(0.5, gt=0)
    position_std_px: float = param(2.0, gt=0)
    place_in_blobs: bool = True
    blob_min_correlation: float = param(0.5, ge=-1, le=1)
    blob_reach_fraction: float = param(0.25, gt=0)
    blob_motion_weight: float = param(0.036, ge=0)

    def check(self) -> None:
        if not (self.use_image or self.use_state):
            raise ValueError("association needs use_image or use_state")
        if not self.confirm_hits <= self.confirm_window:
            raise ValueError("association.confirm_hits must be an integer in [1, confirm_window]")


@dataclass(frozen=True)
class Assignment:
    """``pairs`` (track index, detection index); tracks and detections left over."""

    pairs: tuple[tuple[int, int], ...]
    unmatched_tracks: tuple[int, ...]
    unmatched_detections: tuple[int, ...]
    cost: float
    details: dict[str, object] = field(
        default_factory=dict
    )  # associator-specific (CHNN: energies, gap)


def mahalanobis2(d: np.ndarray, S: np.ndarray) -> float:
    """γ = dᵀ S⁻¹ d."""
    return float(d @ np.linalg.solve(S, d))


def state_log_likelihood(z: np.ndarray, z_pred: np.ndarray, S: np.ndarray) -> tuple[float, float]:
    """``(ln Λ_S, γ)`` of measurement ``z`` under the prediction ``z_pred`` with innovation
    covariance ``S`` (eq. 12-13)."""
    d = np.asarray(z, float) - np.asarray(z_pred, float)
    gamma = mahalanobis2(d, S)
    _sign, logdet = np.linalg.slogdet(S)
    return -0.5 * gamma - 0.5 * d.size * math.log(2 * math.pi) - 0.5 * logdet, gamma


def state_log_likelihoods(
    z: np.ndarray, z_pred: np.ndarray, S: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`state_log_likelihood` of every row of ``z`` (M, R) at once: ``(ln Λ_S (M,), γ
    (M,))``."""
    d = np.asarray(z, float).reshape(-1, len(z_pred)) - np.asarray(z_pred, float)
    Sinv = np.linalg.inv(S)
    gamma = np.einsum("mi,ij,mj->m", d, Sinv, d)
    _sign, logdet = np.linalg.slogdet(S)
    return -0.5 * gamma - 0.5 * d.shape[1] * math.log(2 * math.pi) - 0.5 * logdet, gamma


def padded_cost(cost: np.ndarray, miss_cost: np.ndarray, new_cost: np.ndarray) -> np.ndarray:
    """The (N + M) square matrix of the 2-D assignment with dummies.

    Rows are the N tracks then M dummy rows; columns the M detections then N dummy
    columns. Track n takes detection m at ``cost[n, m]`` or its own dummy column at
    ``miss_cost[n]`` (not detected); detection m left to its own dummy row costs
    ``new_cost[m]`` (new target or false alarm); dummy-to-dummy is free.
    """
    n, m = cost.shape
    big = np.full((n + m, m + n), IMPOSSIBLE)
    big[:n, :m] = np.minimum(cost, IMPOSSIBLE)
    big[np.arange(n), m + np.arange(n)] = miss_cost
    big[n + np.arange(m), np.arange(m)] = new_cost
    big[n:, m:] = 0.0
    return big


def hungarian(cost: np.ndarray, miss_cost: np.ndarray, new_cost: np.ndarray) -> Assignment:
    """The optimal assignment with dummies (Hungarian on :func:`padded_cost`)."""
    cost = np.asarray(cost, float).reshape(len(miss_cost), len(new_cost))
    n, m = cost.shape
    if n == 0 or m == 0:
        return Assignment(
            (),
            tuple(range(n)),
            tuple(range(m)),
            float(np.sum(miss_cost)) + float(np.sum(new_cost)),
        )
    big = padded_cost(cost, np.asarray(miss_cost, float), np.asarray(new_cost, float))
    r, c = linear_sum_assignment(big)
    pairs = tuple(
        (int(i), int(j))
        for i, j in zip(r, c, strict=True)
        if i < n and j < m and big[i, j] < IMPOSSIBLE
    )
    mt = {i for i, _ in pairs}
    md = {j for _, j in pairs}
    return Assignment(
        pairs,
        tuple(i for i in range(n) if i not in mt),
        tuple(j for j in range(m) if j not in md),
        float(big[r, c].sum()),
    )


Associator = Callable[[np.ndarray, np.ndarray, np.ndarray], Assignment]
"""What an associator is: ``(cost (N, M), miss_cost (N,), new_cost (M,)) -> Assignment``
(:func:`hungarian`, :func:`pipeline.stages.chnn.chnn_associator`)."""
