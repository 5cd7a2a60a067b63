"""Members placed inside one detected blob: a region that holds several tracks' predictions is
split among them by their appearance and their motion, in one decision over all of them.

For each member, its template (the grey patch of its last detection on its own) is correlated
over the blob (:func:`cv2.matchTemplate`, normalised correlation coefficient, the template's
box centred anywhere in the blob's box). A place is worth its correlation above a floor less a
weight times its squared Mahalanobis distance from the member's prediction, and is allowed
only inside the prediction's chi-squared gate (as the association's) and within a share of the
template's size of it; the local peaks of worth are the member's candidates. One joint choice
then takes, for every member, one candidate or none: the highest total worth with no two
members' boxes overlapping by more than ``max_overlap_iou`` and the boxes together not much
larger than the blob. Last, a member keeps its place only where its template tells it from the
others (``margin``). A member hidden behind another matches nowhere well and takes none: it
coasts on its prediction inside the blob.

Pure functions over arrays; the detection-driven tracker (``pipeline.trackers.detect``) calls
:func:`place_members` on every blob it keeps as merged.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from pipeline.types import BBox


@dataclass(frozen=True)
class Member:
    """One track inside the blob: its template ``patch`` (grey, float32, the size of its box),
    its predicted centre ``(cx, cy)``, the 2 x 2 covariance ``S`` of that prediction's
    innovation, px^2, and how far from the prediction its centre may be placed, as a share of
    its template's width and height (``reach``, the half-axes of an ellipse; the gate of ``S``
    alone widens while a track coasts)."""

    patch: np.ndarray
    centre: tuple[float, float]
    S: np.ndarray
    reach: float = float("inf")


@dataclass(frozen=True)
class Placement:
    """Where a member was found: its box (the template's size) and the correlation there."""

    box: BBox
    correlation: float


def template_patch(frame: np.ndarray, box: BBox) -> np.ndarray | None:
    """The grey patch of ``frame`` under ``box`` (rounded to whole pixels, clipped to the frame),
    float32; None where under 4 px survive on a side."""
    H, W = frame.shape[:2]
    x0, y0 = max(0, round(box.x)), max(0, round(box.y))
    x1, y1 = min(W, round(box.x2)), min(H, round(box.y2))
    if x1 - x0 < 4 or y1 - y0 < 4:
        return None
    return np.ascontiguousarray(frame[y0:y1, x0:x1], np.float32)


class _Response(NamedTuple):
    """A member's correlation over the blob (its box's top-left corner at ``origin`` + index),
    the worth of each place (correlation above the floor, less the motion's penalty) and the
    mask of the places allowed (centred in the blob, inside the motion's gate and reach)."""

    r: np.ndarray
    worth: np.ndarray
    ok: np.ndarray
    origin: tuple[int, int]


def _response(
    grey: np.ndarray,
    blob: BBox,
    m: Member,
    gate_chi2: float,
    min_correlation: float,
    motion_weight: float,
) -> _Response | None:
    """A member's :class:`_Response`; None where the blob cannot hold its template."""
    h, w = m.patch.shape
    H, W = grey.shape[:2]
    # the search area: every top-left corner that puts the box's centre inside the blob
    x0, y0 = max(0, int(np.floor(blob.x - w / 2))), max(0, int(np.floor(blob.y - h / 2)))
    x1 = min(W, int(np.ceil(blob.x2 + w / 2)))
    y1 = min(H, int(np.ceil(blob.y2 + h / 2)))
    if x1 - x0 < w or y1 - y0 < h:
        return None
    area = np.ascontiguousarray(grey[y0:y1, x0:x1], np.float32)
    r = cv2.matchTemplate(area, m.patch, cv2.TM_CCOEFF_NORMED)
    r = np.nan_to_num(r, nan=-1.0, posinf=-1.0, neginf=-1.0)
    ys, xs = np.mgrid[0 : r.shape[0], 0 : r.shape[1]]
    cx, cy = xs + x0 + w / 2, ys + y0 + h / 2
    inside = (cx >= blob.x) & (cx <= blob.x2) & (cy >= blob.y) & (cy <= blob.y2)
    d = np.stack([cx - m.centre[0], cy - m.centre[1]], -1)
    gamma = np.einsum("...i,ij,...j->...", d, np.linalg.inv(m.S), d)
    near = (d[..., 0] / (m.reach * w)) ** 2 + (d[..., 1] / (m.reach * h)) ** 2 <= 1.0
    worth = (r - min_correlation - motion_weight * gamma).astype(np.float32)
    return _Response(r, worth, inside & (gamma <= gate_chi2) & near, (x0, y0))


def _candidates(
    resp: _Response | None, shape: tuple[int, int], peaks: int
) -> list[tuple[Placement, float]]:
    """A member's local peaks of worth among its allowed places, with their worth, best first
    (at most ``peaks``; only places worth more than nothing)."""
    if resp is None:
        return []
    ok = resp.ok & (resp.worth > 0)
    if not ok.any():
        return []
    h, w = shape
    x0, y0 = resp.origin
    v = np.where(ok, resp.worth, -np.inf).astype(np.float32)
    local = v >= cv2.dilate(v, np.ones((3, 3), np.uint8))
    iy, ix = np.nonzero(local & ok)
    order = np.argsort(-v[iy, ix], kind="stable")[:peaks]
    return [
        (
            Placement(
                BBox(float(ix[k] + x0), float(iy[k] + y0), float(w), float(h)),
                float(resp.r[iy[k], ix[k]]),
            ),
            float(v[iy[k], ix[k]]),
        )
        for k in order
    ]


def _correlation_at(resp: _Response | None, shape: tuple[int, int], box: BBox) -> float:
    """A member's correlation with its box centred where ``box`` is centred (-1 outside its
    search area)."""
    if resp is None:
        return -1.0
    r, (x0, y0) = resp.r, resp.origin
    h, w = shape
    ix, iy = round(box.cx - w / 2) - x0, round(box.cy - h / 2) - y0
    if 0 <= iy < r.shape[0] and 0 <= ix < r.shape[1]:
        return float(r[iy, ix])
    return -1.0


MAX_COMBINATIONS = 4096
"""Above this many combinations of the members' candidates (a crowd in one blob), the joint
choice gives way to a greedy one: the best candidate first, then the next that fits."""


def _fits(taken: list[Placement], blob: BBox, max_overlap_iou: float, max_fill: float) -> bool:
    """No two boxes overlapping beyond ``max_overlap_iou``, together at most ``max_fill`` times
    the blob in area."""
    if len(taken) > 1 and sum(c.box.area for c in taken) > max_fill * blob.area:
        return False
    return not any(a.box.iou(b.box) > max_overlap_iou for a, b in itertools.combinations(taken, 2))


def _joint(
    cands: list[list[tuple[Placement, float]]],
    blob: BBox,
    max_overlap_iou: float,
    max_fill: float,
) -> list[Placement | None]:
    """Every member's candidate or none, the highest total worth among the choices that fit."""
    best: list[Placement | None] = [None] * len(cands)
    best_score = 0.0
    for combo in itertools.product(*[[None, *c] for c in cands]):
        score = sum(c[1] for c in combo if c is not None)
        if score <= best_score:
            continue
        if not _fits([c[0] for c in combo if c is not None], blob, max_overlap_iou, max_fill):
            continue
        best, best_score = [None if c is None else c[0] for c in combo], score
    return best


def _greedy(
    cands: list[list[tuple[Placement, float]]],
    blob: BBox,
    max_overlap_iou: float,
    max_fill: float,
) -> list[Placement | None]:
    """The candidates taken in order of worth, each where it fits with those already taken, at
    most one per member."""
    best: list[Placement | None] = [None] * len(cands)
    order = sorted(
        ((w, k, p) for k, c in enumerate(cands) for p, w in c), key=lambda x: (-x[0], x[1])
    )
    for _, k, p in order:
        if best[k] is None and _fits(
            [q for q in best if q is not None] + [p], blob, max_overlap_iou, max_fill
        ):
            best[k] = p
    return best


def place_members(
    grey: np.ndarray,
    blob: BBox,
    members: list[Member | None],
    *,
    gate_chi2: float,
    min_correlation: float,
    max_overlap_iou: float = 0.5,
    max_fill: float = 1.25,
    margin: float = 0.1,
    motion_weight: float = 0.0,
    peaks: int = 4,
) -> list[Placement | None]:
    """Every member's place in ``blob``, or None where it is found nowhere well enough.

    Parameters
    ----------
    grey : (H, W) array
        The frame the blob was detected in.
    blob : BBox
        The blob's box.
    members : list of Member or None
        The tracks inside the blob (None: a track without a usable template, placed nowhere).
    gate_chi2 : float
        A member's centre stays within this Mahalanobis distance (squared) of its prediction.
    min_correlation : float
        A place is taken only where the template correlates above this, in [-1, 1]; a higher
        value coasts more members, a lower one places them on look-alike parts of the blob.
    max_overlap_iou : float
        Two members' boxes may overlap at most this much (IoU), in (0, 1]; default 0.5.
    max_fill : float
        The members placed hold at most this many times the blob's box in area together, > 0;
        default 1.25: a blob the size of one target holds one (a second track there is a
        duplicate, or hidden), two side by side hold two.
    motion_weight : float
        A place's worth in the joint choice is its correlation above ``min_correlation`` minus
        this times its squared Mahalanobis distance from the member's prediction, >= 0;
        default 0 (correlation alone). A place worth nothing is not taken.
    margin : float
        A member is placed only where its template correlates at least this much better than
        at every other member's place, >= 0; default 0.1: two look-alikes crossing cannot be
        told apart inside their blob, and both coast on their motion instead of swapping.
    peaks : int
        Candidate places kept per member, >= 1; default 4 (the joint choice weighs
        ``(peaks + 1) ** members`` combinations; beyond ``MAX_COMBINATIONS`` a greedy choice
        takes the best candidates first).

    Returns
    -------
    list of Placement or None
        In the order of ``members``.
    """
    resp = [
        None if m is None else _response(grey, blob, m, gate_chi2, min_correlation, motion_weight)
        for m in members
    ]
    shapes = [(0, 0) if m is None else m.patch.shape for m in members]
    cands = [_candidates(r, sh, peaks) for r, sh in zip(resp, shapes, strict=True)]
    n_combos = math.prod(len(c) + 1 for c in cands)
    if n_combos <= MAX_COMBINATIONS:
        best = _joint(cands, blob, max_overlap_iou, max_fill)
    else:
        best = _greedy(cands, blob, max_overlap_iou, max_fill)
    # a member is placed only where its template tells it from the others: its own place
    # matches it better, by ``margin``, than every other member's place (or prediction, where
    # that one is not placed) does, and better than the other members' templates match it
    # (look-alikes crossing cannot be told apart: they coast on their motion)
    out = list(best)
    where = [
        None if m is None else (q.box if q is not None else BBox.from_center(*m.centre, 1, 1))
        for m, q in zip(members, best, strict=True)
    ]
    for k, p in enumerate(best):
        if p is None:
            continue
        rival = -1.0
        for j, b in enumerate(where):
            if j == k or b is None:
                continue
            rival = max(
                rival,
                _correlation_at(resp[k], shapes[k], b),
                _correlation_at(resp[j], shapes[j], p.box),
            )
        if p.correlation - rival < margin:
            out[k] = None
    return out
