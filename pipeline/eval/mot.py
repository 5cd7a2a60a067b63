"""Many-target metrics: CLEAR-MOT (MOTA, MOTP), ID switches, IDF1, the purity matrix, HOTA.

Written on scipy's ``linear_sum_assignment`` (motmetrics 1.4 fails on NumPy 2 and
TrackEval needs the non-headless OpenCV). Conventions:

* A truth box and a track box may be matched when IoU >= ``iou_threshold`` (0.5).
* Per frame (CLEAR-MOT, as motmetrics does): a truth target keeps last frame's track if
  they still overlap enough; the rest is a Hungarian assignment maximising IoU.
* An ID switch is counted when a target is matched to a different track than at its
  previous match.
* ``motp`` is the mean IoU of the matched pairs, in [0, 1] (motmetrics reports 1 - IoU).
* IDF1 = 2 IDTP / (2 IDTP + IDFP + IDFN) with the global one-to-one truth/track
  assignment that maximises IDTP (frames where the pair overlaps by ``iou_threshold``).
* Purity: ``P[i, j]`` = fraction of the frames where target i is present in which it
  is matched to track j; the last column, ``none``, counts unmatched frames; rows sum to 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from pipeline.eval.single import iou_matrix, iou_rows


@dataclass(frozen=True)
class FrameMatching:
    """Per-frame matches: ``matches[f]`` is a list of ``(gt_id, track_id, iou)``."""

    matches: list[list[tuple[int, int, float]]]
    n_gt: np.ndarray  # truth boxes per frame
    n_tracks: np.ndarray  # track boxes per frame


def _present(table: dict[int, np.ndarray], f: int) -> tuple[list[int], np.ndarray]:
    ids = [i for i, b in table.items() if not np.isnan(b[f]).any()]
    boxes = np.array([table[i][f] for i in ids]).reshape(len(ids), 4)
    return ids, boxes


def match_frames(
    gt: dict[int, np.ndarray], tracks: dict[int, np.ndarray], n_frames: int, iou_threshold: float = 0.5
) -> FrameMatching:
    """CLEAR-MOT frame-by-frame matching of truth and tracks."""
    last: dict[int, int] = {}
    out, n_gt, n_tr = [], np.zeros(n_frames, int), np.zeros(n_frames, int)
    for f in range(n_frames):
        gids, gb = _present(gt, f)
        tids, tb = _present(tracks, f)
        n_gt[f], n_tr[f] = len(gids), len(tids)
        iou = iou_matrix(gb, tb)
        pairs: list[tuple[int, int, float]] = []
        used_g, used_t = set(), set()
        for gi, g in enumerate(gids):  # continuation of last frame's matches
            t = last.get(g)
            if t is not None and t in tids:
                ti = tids.index(t)
                if ti not in used_t and iou[gi, ti] >= iou_threshold:
                    pairs.append((g, t, float(iou[gi, ti])))
                    used_g.add(gi)
                    used_t.add(ti)
        rest_g = [i for i in range(len(gids)) if i not in used_g]
        rest_t = [j for j in range(len(tids)) if j not in used_t]
        if rest_g and rest_t:
            sub = iou[np.ix_(rest_g, rest_t)]
            cost = np.where(sub >= iou_threshold, 1.0 - sub, 1e6)
            r, c = linear_sum_assignment(cost)
            for a, b in zip(r, c, strict=True):
                if sub[a, b] >= iou_threshold:
                    pairs.append((gids[rest_g[a]], tids[rest_t[b]], float(sub[a, b])))
        for g, t, _ in pairs:
            last[g] = t
        out.append(pairs)
    return FrameMatching(out, n_gt, n_tr)


def clear_mot(m: FrameMatching) -> dict[str, float]:
    """MOTA, MOTP, ID switches, FP, FN from a frame matching."""
    prev: dict[int, int] = {}
    switches = 0
    matched = 0
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
    mota = 1.0 - (fn + fp + switches) / total_gt if total_gt else float("nan")
    return {
        "mota": float(mota),
        "motp": float(iou_sum / matched) if matched else float("nan"),
        "id_switches": int(switches),
        "false_positives": int(fp),
        "misses": int(fn),
        "matches": int(matched),
    }


def overlap_counts(
    gt: dict[int, np.ndarray], tracks: dict[int, np.ndarray], iou_threshold: float = 0.5
) -> np.ndarray:
    """``n[i, j]``: frames where truth i and track j overlap by ``>= iou_threshold``."""
    gids, tids = list(gt), list(tracks)
    n = np.zeros((len(gids), len(tids)), int)
    for i, g in enumerate(gids):
        for j, t in enumerate(tracks):
            n[i, j] = int((iou_rows(gt[g], tracks[t]) >= iou_threshold).sum())
    return n


def idf1(gt: dict[int, np.ndarray], tracks: dict[int, np.ndarray], iou_threshold: float = 0.5) -> dict[str, object]:
    """IDF1 with the global truth-to-track assignment; also returns the mapping."""
    n_g = sum(int((~np.isnan(b).any(axis=1)).sum()) for b in gt.values())
    n_t = sum(int((~np.isnan(b).any(axis=1)).sum()) for b in tracks.values())
    mapping: dict[int, int] = {}
    idtp = 0
    if gt and tracks:
        n = overlap_counts(gt, tracks, iou_threshold)
        r, c = linear_sum_assignment(-n)
        gids, tids = list(gt), list(tracks)
        for a, b in zip(r, c, strict=True):
            if n[a, b] > 0:
                mapping[gids[a]] = tids[b]
                idtp += int(n[a, b])
    idfp, idfn = n_t - idtp, n_g - idtp
    denom = 2 * idtp + idfp + idfn
    return {
        "idf1": float(2 * idtp / denom) if denom else float("nan"),
        "idp": float(idtp / n_t) if n_t else float("nan"),
        "idr": float(idtp / n_g) if n_g else float("nan"),
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
        "target_purity": {str(g): float(mat[i, :-1].max()) if track_ids else 0.0 for i, g in enumerate(gt_ids)},
        "overall": overall,
    }


def hota(
    gt: dict[int, np.ndarray],
    tracks: dict[int, np.ndarray],
    n_frames: int,
    alphas: np.ndarray | None = None,
) -> dict[str, float]:
    """HOTA (Luiten et al. 2021) averaged over IoU thresholds alpha = 0.05..0.95.

    Per alpha: per-frame Hungarian matching maximising IoU among pairs with IoU >= alpha
    (TrackEval additionally weights by a global association score; we use the plain IoU
    matching, documented as the difference), then ``DetA = TP / (TP + FN + FP)``,
    ``AssA = mean over TP of TPA / (TPA + FNA + FPA)``, ``HOTA = sqrt(DetA * AssA)``.
    """
    if alphas is None:
        alphas = np.arange(0.05, 0.96, 0.05)
    gids, tids = list(gt), list(tracks)
    if not gids:
        return {"hota": float("nan"), "deta": float("nan"), "assa": float("nan")}
    gidx = {g: i for i, g in enumerate(gids)}
    tidx = {t: j for j, t in enumerate(tids)}
    frames = []
    for f in range(n_frames):
        gi, gb = _present(gt, f)
        ti, tb = _present(tracks, f)
        frames.append(([gidx[g] for g in gi], [tidx[t] for t in ti], iou_matrix(gb, tb)))
    hs, ds, as_ = [], [], []
    for alpha in alphas:
        tp_pairs = np.zeros((len(gids), len(tids)))
        tp = fn = fp = 0
        matched_list = []
        gt_count = np.zeros(len(gids))
        tr_count = np.zeros(len(tids))
        for g_list, t_list, iou in frames:
            for g in g_list:
                gt_count[g] += 1
            for t in t_list:
                tr_count[t] += 1
            if g_list and t_list:
                cost = np.where(iou >= alpha - 1e-12, -iou, 1e6)
                r, c = linear_sum_assignment(cost)
                ok = iou[r, c] >= alpha - 1e-12
                for a, b in zip(r[ok], c[ok], strict=True):
                    tp_pairs[g_list[a], t_list[b]] += 1
                    matched_list.append((g_list[a], t_list[b]))
                n_ok = int(ok.sum())
            else:
                n_ok = 0
            tp += n_ok
            fn += len(g_list) - n_ok
            fp += len(t_list) - n_ok
        deta = tp / (tp + fn + fp) if (tp + fn + fp) else 0.0
        if tp:
            tpa = tp_pairs
            ass = tpa / np.maximum(gt_count[:, None] + tr_count[None, :] - tpa, 1)
            assa = float(sum(ass[g, t] for g, t in matched_list) / tp)
        else:
            assa = 0.0
        hs.append(np.sqrt(deta * assa))
        ds.append(deta)
        as_.append(assa)
    return {"hota": float(np.mean(hs)), "deta": float(np.mean(ds)), "assa": float(np.mean(as_))}
