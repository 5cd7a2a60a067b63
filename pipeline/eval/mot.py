"""Many-target metrics: CLEAR-MOT (MOTA, MOTP), ID switches, IDF1, the purity matrix, HOTA.

By default every score is computed as TrackEval computes it for MOTChallenge (the numbers
MOTChallenge publishes; ``trackeval/metrics/clear.py``, ``identity.py``, ``hota.py`` and the
``MotChallenge2DBox`` dataset), on scipy's ``linear_sum_assignment``:

* Similarity is TrackEval's box IoU (corners from ``x, y, w, h``, intersection over union,
  0 for an empty box), kept in [0, 1].
* CLEAR (``rule="trackeval"``): per frame one Hungarian assignment of truth to tracks on
  ``1000 * continues + IoU`` among the pairs with ``IoU >= 0.5``, where ``continues`` marks
  the track a truth target was matched to in the *previous frame* (a match is carried over
  one frame, not across a gap). An ID switch is a match to another track than the target's
  last match at any earlier frame. ``MOTA = (TP - FP - IDSW) / max(1, TP + FN)``,
  ``MOTP`` the mean IoU of the matches (TrackEval's similarity; MOTChallenge prints it x100).
* ``rule="motmetrics"``: py-motmetrics 1.4's rule instead: a truth target keeps the track of
  its last match at *any* earlier frame while they still overlap by ``IoU >= 0.5``, the rest
  is a Hungarian assignment minimising ``1 - IoU``; ``MOTP`` is then the mean IoU of the
  matches (motmetrics reports ``1 - IoU``), NaN when nothing matched. The two rules differ
  when a target is missed for a frame and comes back to the same track.
* Identity (IDF1, IDP, IDR): one global one-to-one truth/track assignment that minimises
  IDFN + IDFP, counting the frames where a pair overlaps by ``IoU >= 0.5`` (both rules).
* HOTA: per frame a Hungarian assignment maximising IoU weighted by the pair's global
  alignment score (its IoU-weighted co-occurrence over the sequence), then per
  ``alpha = 0.05, 0.10, ..., 0.95`` the matches with ``IoU >= alpha`` give DetA, AssA and
  LocA; ``HOTA = mean over alpha of sqrt(DetA * AssA)``.
* Distractors (:func:`drop_distractor_matches`, TrackEval's MOT17 preprocessing): in each
  frame truth and distractor boxes together are assigned to the track boxes (Hungarian on
  IoU among pairs with ``IoU >= 0.5``); a track box assigned to a distractor is removed
  before every score, so a box on an object that is not a target is neither a true nor a
  false positive.
* Purity: ``P[i, j]`` = fraction of the frames where target i is present in which it is
  matched (CLEAR matching) to track j; the last column, ``none``, counts unmatched frames;
  rows sum to 1.

Truth and track ids are ordered by id within a frame (TrackEval keeps the file's row order,
which only matters for exact ties of the assignment).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

MATCH_RULES = ("trackeval", "motmetrics")
EPS = np.finfo("float").eps
HOTA_ALPHAS = np.arange(0.05, 0.99, 0.05)
"""TrackEval's HOTA thresholds (19 values, 0.05 to 0.95)."""


def box_ious(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(n, m)`` IoU of ``x, y, w, h`` rows as TrackEval computes it (``_calculate_box_ious``),
    clipped to [0, 1]."""
    if a.shape[0] == 0 or b.shape[0] == 0:
        return np.zeros((a.shape[0], b.shape[0]))
    a = np.column_stack([a[:, 0], a[:, 1], a[:, 0] + a[:, 2], a[:, 1] + a[:, 3]])
    b = np.column_stack([b[:, 0], b[:, 1], b[:, 0] + b[:, 2], b[:, 1] + b[:, 3]])
    lo = np.minimum(a[:, None, :], b[None, :, :])
    hi = np.maximum(a[:, None, :], b[None, :, :])
    inter = np.maximum(lo[..., 2] - hi[..., 0], 0) * np.maximum(lo[..., 3] - hi[..., 1], 0)
    area1 = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area2 = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area1[:, None] + area2[None, :] - inter
    inter[area1 <= 0 + EPS, :] = 0
    inter[:, area2 <= 0 + EPS] = 0
    inter[union <= 0 + EPS] = 0
    union[union <= 0 + EPS] = 1
    return np.clip(inter / union, 0.0, 1.0)


def drop_distractor_matches(
    gt: dict[int, np.ndarray], tracks: dict[int, np.ndarray], distractors: dict[int, np.ndarray]
) -> dict[int, np.ndarray]:
    """``tracks`` without the boxes that match a distractor (TrackEval's MOT17 preprocessing).

    Parameters
    ----------
    gt, distractors : dict of int to (N, 4) arrays
        Truth boxes and distractor boxes per id, ``x, y, w, h``, NaN rows absent.
    tracks : dict of int to (N, 4) arrays
        Track boxes per id.

    Returns
    -------
    dict of int to (N, 4) arrays
        Copies of ``tracks`` with the removed boxes set to NaN; ``tracks`` itself when
        there are no distractors.

    Examples
    --------
    >>> import numpy as np
    >>> nan = [np.nan] * 4
    >>> gt = {1: np.array([[0, 0, 10, 10.0]])}
    >>> car = {9: np.array([[50, 50, 20, 10.0]])}
    >>> tr = {1: np.array([[1, 0, 10, 10.0]]), 2: np.array([[51, 50, 20, 10.0]]),
    ...       3: np.array([nan])}
    >>> out = drop_distractor_matches(gt, tr, car)
    >>> bool(np.isnan(out[2][0]).all()), bool(np.isnan(out[1][0]).any())
    (True, False)
    """
    if not distractors or not tracks:
        return tracks
    n = next(iter(tracks.values())).shape[0]
    out = {t: b.copy() for t, b in tracks.items()}
    rows = [*gt.values(), *distractors.values()]
    is_distractor = np.array([False] * len(gt) + [True] * len(distractors))
    tids = list(tracks)
    for f in range(n):
        present = [k for k, b in enumerate(rows) if f < b.shape[0] and not np.isnan(b[f]).any()]
        if not any(is_distractor[k] for k in present):
            continue
        tpresent = [t for t in tids if not np.isnan(tracks[t][f]).any()]
        if not tpresent:
            continue
        sim = box_ious(
            np.array([rows[k][f] for k in present]), np.array([tracks[t][f] for t in tpresent])
        )
        score = sim.copy()
        score[score < 0.5 - EPS] = 0
        r, c = linear_sum_assignment(-score)
        for a, b in zip(r, c, strict=True):
            if score[a, b] > 0 + EPS and is_distractor[present[a]]:
                out[tpresent[b]][f] = np.nan
    return out


@dataclass(frozen=True)
class SequenceData:
    """Per frame: indices of the present truth targets and tracks (into ``gt_ids`` / ``track_ids``)
    and their IoU matrix."""

    gt_ids: tuple[int, ...]
    track_ids: tuple[int, ...]
    frames: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]

    @property
    def gt_dets(self) -> int:
        return int(sum(g.size for g, _, _ in self.frames))

    @property
    def track_dets(self) -> int:
        return int(sum(t.size for _, t, _ in self.frames))


def sequence_data(
    gt: dict[int, np.ndarray], tracks: dict[int, np.ndarray], n_frames: int
) -> SequenceData:
    """Collect truth (``gt[id]``: (N, 4), NaN rows absent) and tracks frame by frame."""
    gids, tids = tuple(sorted(gt)), tuple(sorted(tracks))
    G = np.stack([gt[g][:n_frames] for g in gids]) if gids else np.zeros((0, n_frames, 4))
    T = np.stack([tracks[t][:n_frames] for t in tids]) if tids else np.zeros((0, n_frames, 4))
    g_ok = ~np.isnan(G).any(axis=2)
    t_ok = ~np.isnan(T).any(axis=2)
    frames = []
    for f in range(n_frames):
        gi = np.nonzero(g_ok[:, f])[0] if gids else np.zeros(0, int)
        ti = np.nonzero(t_ok[:, f])[0] if tids else np.zeros(0, int)
        frames.append(
            (
                gi,
                ti,
                box_ious(G[gi, f], T[ti, f])
                if gi.size and ti.size
                else np.zeros((gi.size, ti.size)),
            )
        )
    return SequenceData(gids, tids, tuple(frames))


@dataclass(frozen=True)
class FrameMatching:
    """Per-frame CLEAR matches: ``matches[f]`` is a list of ``(gt_id, track_id, iou)``."""

    matches: list[list[tuple[int, int, float]]]
    n_gt: np.ndarray  # truth boxes per frame
    n_tracks: np.ndarray  # track boxes per frame
    rule: str = "trackeval"


def match_frames(
    gt: dict[int, np.ndarray],
    tracks: dict[int, np.ndarray],
    n_frames: int,
    iou_threshold: float = 0.5,
    rule: str = "trackeval",
    data: SequenceData | None = None,
) -> FrameMatching:
    """CLEAR-MOT frame-by-frame matching of truth and tracks by ``rule`` (see the module doc)."""
    if rule not in MATCH_RULES:
        raise ValueError(f"rule must be one of {MATCH_RULES}; got {rule!r}")
    d = data if data is not None else sequence_data(gt, tracks, n_frames)
    n_g = len(d.gt_ids)
    out: list[list[tuple[int, int, float]]] = []
    n_gt = np.array([g.size for g, _, _ in d.frames], int)
    n_tr = np.array([t.size for _, t, _ in d.frames], int)
    prev_step = np.full(
        n_g, -1
    )  # trackeval: the track index each target matched in the previous frame
    last: dict[int, int] = {}  # motmetrics: the track index of each target's last match
    gpos = {g: k for k, g in enumerate(d.gt_ids)}
    tpos_all = {t: k for k, t in enumerate(d.track_ids)}
    for gi, ti, sim in d.frames:
        pairs: list[tuple[int, int, float]] = []
        if gi.size == 0 or ti.size == 0:  # TrackEval skips the frame: its matches carry over
            out.append(pairs)
            continue
        if rule == "trackeval":
            score = 1000.0 * (ti[None, :] == prev_step[gi][:, None]) + sim
            score[sim < iou_threshold - EPS] = 0
            r, c = linear_sum_assignment(-score)
            ok = score[r, c] > 0 + EPS
            prev_step[:] = -1
            for a, b in zip(r[ok], c[ok], strict=True):
                pairs.append((d.gt_ids[gi[a]], d.track_ids[ti[b]], float(sim[a, b])))
                prev_step[gi[a]] = ti[b]
        else:
            used_g: set[int] = set()
            used_t: set[int] = set()
            tpos = {int(t): j for j, t in enumerate(ti)}
            for a, g in enumerate(gi):  # continuation of the last match, at any earlier frame
                j = tpos.get(last.get(int(g), -1))
                if j is not None and j not in used_t and sim[a, j] >= iou_threshold:
                    pairs.append((d.gt_ids[g], d.track_ids[ti[j]], float(sim[a, j])))
                    used_g.add(a)
                    used_t.add(j)
            rest_g = [a for a in range(gi.size) if a not in used_g]
            rest_t = [j for j in range(ti.size) if j not in used_t]
            if rest_g and rest_t:
                sub = sim[np.ix_(rest_g, rest_t)]
                cost = np.where(sub >= iou_threshold, 1.0 - sub, 1e6)
                r, c = linear_sum_assignment(cost)
                for a, b in zip(r, c, strict=True):
                    if sub[a, b] >= iou_threshold:
                        pairs.append(
                            (d.gt_ids[gi[rest_g[a]]], d.track_ids[ti[rest_t[b]]], float(sub[a, b]))
                        )
            for g, t, _ in pairs:
                last[gpos[g]] = tpos_all[t]
        out.append(pairs)
    return FrameMatching(out, n_gt, n_tr, rule)


def clear_mot(m: FrameMatching) -> dict[str, float]:
    """MOTA, MOTP, ID switches, FP, FN from a frame matching (formulas of its rule, module doc)."""
    prev: dict[int, int] = {}
    switches = matched = 0
    iou_sum = 0.0
    for pairs in m.matches:
        for g, t, iou in pairs:
            if g in prev and prev[g] != t:
                switches += 1
            prev[g] = t
            matched += 1
            iou_sum += iou
    total_gt = int(m.n_gt.sum())
    fn = total_gt - matched
    fp = int(m.n_tracks.sum()) - matched
    if m.rule == "trackeval":
        mota = (matched - fp - switches) / max(1.0, matched + fn)
        motp = iou_sum / max(1.0, matched)
    else:
        mota = 1.0 - (fn + fp + switches) / total_gt if total_gt else float("nan")
        motp = iou_sum / matched if matched else float("nan")
    return {
        "mota": float(mota),
        "motp": float(motp),
        "id_switches": int(switches),
        "false_positives": int(fp),
        "misses": int(fn),
        "matches": int(matched),
    }


def idf1(
    gt: dict[int, np.ndarray],
    tracks: dict[int, np.ndarray],
    iou_threshold: float = 0.5,
    n_frames: int | None = None,
    data: SequenceData | None = None,
) -> dict[str, object]:
    """IDF1, IDP, IDR (TrackEval's Identity) and the truth -> track mapping of the global
    assignment.

    The mapping holds the pairs of the assignment that share at least one matched frame.
    """
    n = (
        n_frames
        if n_frames is not None
        else max([b.shape[0] for b in (*gt.values(), *tracks.values())], default=0)
    )
    d = data if data is not None else sequence_data(gt, tracks, n)
    n_g, n_t = len(d.gt_ids), len(d.track_ids)
    gt_dets, tr_dets = d.gt_dets, d.track_dets
    if tr_dets == 0 or gt_dets == 0:
        idtp, mapping = 0, {}
    else:
        pot = np.zeros((n_g, n_t))
        gt_count, tr_count = np.zeros(n_g), np.zeros(n_t)
        for gi, ti, sim in d.frames:
            a, b = np.nonzero(sim >= iou_threshold)
            np.add.at(pot, (gi[a], ti[b]), 1)
            gt_count[gi] += 1
            tr_count[ti] += 1
        fp_mat = np.zeros((n_g + n_t, n_g + n_t))
        fn_mat = np.zeros((n_g + n_t, n_g + n_t))
        fp_mat[n_g:, :n_t] = 1e10
        fn_mat[:n_g, n_t:] = 1e10
        for g in range(n_g):
            fn_mat[g, :n_t] = gt_count[g]
            fn_mat[g, n_t + g] = gt_count[g]
        for t in range(n_t):
            fp_mat[:n_g, t] = tr_count[t]
            fp_mat[t + n_g, t] = tr_count[t]
        fn_mat[:n_g, :n_t] -= pot
        fp_mat[:n_g, :n_t] -= pot
        r, c = linear_sum_assignment(fn_mat + fp_mat)
        idfn = int(fn_mat[r, c].sum())
        idtp = int(gt_count.sum()) - idfn
        mapping = {
            d.gt_ids[a]: d.track_ids[b]
            for a, b in zip(r, c, strict=True)
            if a < n_g and b < n_t and pot[a, b] > 0
        }
    idfp, idfn = tr_dets - idtp, gt_dets - idtp
    return {
        "idf1": float(idtp / max(1.0, idtp + 0.5 * idfp + 0.5 * idfn)),
        "idp": float(idtp / max(1.0, idtp + idfp)),
        "idr": float(idtp / max(1.0, idtp + idfn)),
        "mapping": mapping,
    }


def purity_matrix(
    gt: dict[int, np.ndarray], tracks: dict[int, np.ndarray], m: FrameMatching
) -> dict[str, object]:
    """The purity matrix with row/column ids, target purities and overall purity."""
    gt_ids, track_ids = list(gt), list(tracks)
    col = {t: j for j, t in enumerate(track_ids)}
    row = {g: i for i, g in enumerate(gt_ids)}
    counts = np.zeros((len(gt_ids), len(track_ids) + 1))
    for pairs in m.matches:
        for g, t, _iou in pairs:
            counts[row[g], col[t]] += 1
    present = np.array([(~np.isnan(gt[g]).any(axis=1)).sum() for g in gt_ids], dtype=float)
    counts[:, -1] = present - counts[:, :-1].sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mat = np.where(present[:, None] > 0, counts / present[:, None], 0.0)
    best = counts[:, :-1].max(axis=1) if track_ids else np.zeros(len(gt_ids))
    overall = float(best.sum() / present.sum()) if present.sum() else float("nan")
    return {
        "rows": [str(g) for g in gt_ids],
        "columns": [str(t) for t in track_ids] + ["none"],
        "matrix": [[round(float(v), 6) for v in r] for r in mat],
        "target_purity": {
            str(g): float(mat[i, :-1].max()) if track_ids else 0.0 for i, g in enumerate(gt_ids)
        },
        "overall": overall,
    }


def hota(
    gt: dict[int, np.ndarray],
    tracks: dict[int, np.ndarray],
    n_frames: int,
    data: SequenceData | None = None,
) -> dict[str, float]:
    """HOTA, DetA, AssA and LocA as TrackEval computes them (means over ``HOTA_ALPHAS``; module
    doc)."""
    d = data if data is not None else sequence_data(gt, tracks, n_frames)
    A = HOTA_ALPHAS.size
    n_g, n_t = len(d.gt_ids), len(d.track_ids)
    if d.track_dets == 0 or d.gt_dets == 0:
        return {"hota": 0.0, "deta": 0.0, "assa": 0.0, "loca": 1.0}
    pot = np.zeros((n_g, n_t))
    gt_count = np.zeros((n_g, 1))
    tr_count = np.zeros((1, n_t))
    for gi, ti, sim in d.frames:
        denom = sim.sum(0)[None, :] + sim.sum(1)[:, None] - sim
        sim_iou = np.zeros_like(sim)
        ok = denom > 0 + EPS
        sim_iou[ok] = sim[ok] / denom[ok]
        pot[gi[:, None], ti[None, :]] += sim_iou
        gt_count[gi] += 1
        tr_count[0, ti] += 1
    align = pot / (gt_count + tr_count - pot)
    tp, fn, fp, loca = np.zeros(A), np.zeros(A), np.zeros(A), np.zeros(A)
    counts = [np.zeros_like(pot) for _ in range(A)]
    for gi, ti, sim in d.frames:
        if gi.size == 0:
            fp += ti.size
            continue
        if ti.size == 0:
            fn += gi.size
            continue
        score = align[gi[:, None], ti[None, :]] * sim
        r, c = linear_sum_assignment(-score)
        for a, alpha in enumerate(HOTA_ALPHAS):
            ok = sim[r, c] >= alpha - EPS
            ar, ac = r[ok], c[ok]
            tp[a] += ar.size
            fn[a] += gi.size - ar.size
            fp[a] += ti.size - ar.size
            if ar.size:
                loca[a] += sim[ar, ac].sum()
                counts[a][gi[ar], ti[ac]] += 1
    assa = np.zeros(A)
    for a in range(A):
        mc = counts[a]
        ass = mc / np.maximum(1, gt_count + tr_count - mc)
        assa[a] = np.sum(mc * ass) / np.maximum(1, tp[a])
    loca = np.maximum(1e-10, loca) / np.maximum(1e-10, tp)
    deta = tp / np.maximum(1, tp + fn + fp)
    h = np.sqrt(deta * assa)
    return {
        "hota": float(h.mean()),
        "deta": float(deta.mean()),
        "assa": float(assa.mean()),
        "loca": float(loca.mean()),
    }
