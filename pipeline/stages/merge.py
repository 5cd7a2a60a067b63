"""Merging and splitting of targets during mutual occlusion (dual-channel paper §2.3, eq. 10-11).

Small decisions kept apart from the code that acts on them:

* :func:`merge_test` is eq. 10: two targets merge when, on rows and on columns, their
  mean-shift positions are closer than the sum of their scales,
  ``|y_{1,1} - y_{1,2}| < h_1 + h_2`` with h the half-size of each box: their boxes overlap;
* :func:`merge_groups` joins every pair that merges into groups (beyond the paper, which
  treats pairs: three or more targets can merge at once);
* :func:`choose_foreground`: the target whose colour matches its model best (eq. 3) is in
  front, the others are occluded;
* :func:`eq11` places an occluded target of a pair by mirroring the foreground about the
  merged blob's centre, ``y_{1,2} = 2 y_2 - y_{1,1}``; :func:`inside_blob` keeps a member's
  box inside the merged blob's box;
* :func:`associate` re-associates targets with the separate blobs of a split by a global
  assignment (Hungarian) on a cost matrix;
* beyond the paper, :func:`lookalike_sets` finds targets whose colour models match each
  other (their mean shifts cannot tell them apart) and :func:`kmeans_shares` locates such
  members inside a merged blob from its pixels.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import linear_sum_assignment

from pipeline.types import BBox


def merge_test(a: BBox, b: BBox, scale: float = 1.0) -> bool:
    """Eq. 10 on rows and columns: ``|cx_a - cx_b| < (w_a + w_b)/2`` and ``|cy_a - cy_b| < (h_a +
    h_b)/2`` (``scale`` < 1 asks for a deeper overlap)."""
    return (
        abs(a.cx - b.cx) < scale * (a.w + b.w) / 2 and abs(a.cy - b.cy) < scale * (a.h + b.h) / 2
    )


def merge_groups(
    boxes: dict[int, BBox],
    strict: frozenset[int] | set[int] = frozenset(),
    strict_scale: float = 1.0,
) -> list[tuple[int, ...]]:
    """Groups (sorted id tuples, two or more members) of targets linked by pairwise merges; a pair
    with a member in ``strict`` (just split) merges only under ``merge_test(..., strict_scale)``.
    """
    ids = sorted(boxes)
    parent = {i: i for i in ids}

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for k, i in enumerate(ids):
        for j in ids[k + 1 :]:
            if merge_test(
                boxes[i], boxes[j], strict_scale if (i in strict or j in strict) else 1.0
            ):
                parent[find(i)] = find(j)
    groups: dict[int, list[int]] = {}
    for i in ids:
        groups.setdefault(find(i), []).append(i)
    return sorted(tuple(sorted(g)) for g in groups.values() if len(g) >= 2)


def choose_foreground(rhos: dict[int, float], distances: dict[int, float] | None = None) -> int:
    """The target with the highest colour match; without colour (NaN), the one nearest the blob
    centre."""
    valid = {i: r for i, r in rhos.items() if not math.isnan(r)}
    if valid:
        return max(sorted(valid), key=lambda i: valid[i])
    if distances:
        return min(sorted(distances), key=lambda i: distances[i])
    return min(rhos)


def eq11(
    merged_center: tuple[float, float], foreground: tuple[float, float]
) -> tuple[float, float]:
    """Eq. 11: the occluded target of a pair, ``2 y2 - y_foreground``."""
    return (2 * merged_center[0] - foreground[0], 2 * merged_center[1] - foreground[1])


def inside_blob(
    center: tuple[float, float], size: tuple[float, float], blob: BBox
) -> tuple[float, float]:
    """``center`` moved the least distance that puts a box of ``size`` inside ``blob``, per axis;
    on an axis where the box is larger than the blob, the blob's centre."""
    out = []
    for c, s, lo, hi in (
        (center[0], size[0], blob.x, blob.x2),
        (center[1], size[1], blob.y, blob.y2),
    ):
        a, b = lo + s / 2, hi - s / 2
        out.append((lo + hi) / 2 if a > b else min(max(c, a), b))
    return out[0], out[1]


def association_cost(
    rho: np.ndarray, distance: np.ndarray, scale: np.ndarray, motion_weight: float
) -> np.ndarray:
    """Cost of giving blob j to target i: ``(1 - rho_ij) + w * d_ij / scale_i``.

    ``rho`` is the colour match of target i's model at blob j (the paper's criterion), ``d``
    the distance from target i's predicted position to blob j and ``scale`` target i's
    size (diagonal): beyond the paper, the motion term separates look-alikes that colour
    cannot. NaN colour (no colour channel) counts as no information (0.5).
    """
    r = np.where(np.isnan(rho), 0.5, rho)
    return (1.0 - r) + motion_weight * distance / scale[:, None]


def associate(cost: np.ndarray) -> list[tuple[int, int]]:
    """Global minimum-cost assignment (rows = targets, columns = blobs); handles empty matrices."""
    if cost.size == 0:
        return []
    r, c = linear_sum_assignment(cost)
    return [(int(i), int(j)) for i, j in zip(r, c, strict=True)]


def kmeans_shares(
    mask: np.ndarray,
    origin: tuple[int, int],
    centers: list[tuple[float, float]],
    sizes: list[tuple[float, float]],
    iterations: int = 5,
) -> list[tuple[float, float] | None]:
    """Centres of the members of a merged blob by k-means on its pixels (beyond the paper).

    Starts from the predicted ``centers``; each pass gives every pixel of ``mask`` to the
    member whose centre is nearest in size-normalized distance and moves each centre to
    the mean of its pixels. Side-by-side bodies come out at their own centroids whatever
    their colours, which is what look-alikes need. A member left with no pixels gets None.
    """
    ys, xs = np.nonzero(mask)
    if xs.size == 0:
        return [None] * len(centers)
    px = xs.astype(np.float64) + origin[0] + 0.5
    py = ys.astype(np.float64) + origin[1] + 0.5
    c = np.array(centers, float)
    sz = np.array(sizes, float)
    out: list[tuple[float, float] | None] = [None] * len(centers)
    for _ in range(max(iterations, 1)):
        d = ((px[None, :] - c[:, :1]) / sz[:, :1]) ** 2 + (
            (py[None, :] - c[:, 1:]) / sz[:, 1:]
        ) ** 2
        owner = np.argmin(d, axis=0)
        for k in range(len(centers)):
            sel = owner == k
            if sel.any():
                c[k] = (px[sel].mean(), py[sel].mean())
                out[k] = (float(c[k, 0]), float(c[k, 1]))
            else:
                out[k] = None
    return out


def lookalike_sets(models: dict[int, np.ndarray], min_rho: float) -> list[tuple[int, ...]]:
    """Groups of targets whose colour models match each other at least ``min_rho`` (eq. 3)."""
    ids = sorted(models)
    parent = {i: i for i in ids}

    def find(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for k, i in enumerate(ids):
        for j in ids[k + 1 :]:
            if float(np.sqrt(models[i] * models[j]).sum()) >= min_rho:
                parent[find(i)] = find(j)
    groups: dict[int, list[int]] = {}
    for i in ids:
        groups.setdefault(find(i), []).append(i)
    return sorted(tuple(g) for g in groups.values() if len(g) >= 2)


def choose_foreground_stable(
    rhos: dict[int, float],
    previous: int | None,
    margin: float,
    distances: dict[int, float] | None = None,
) -> int:
    """:func:`choose_foreground` with hysteresis: the previous foreground keeps its role unless
    another target's colour match exceeds its own by ``margin``."""
    best = choose_foreground(rhos, distances)
    if previous is None or previous not in rhos or previous == best:
        return best
    rp, rb = rhos[previous], rhos[best]
    if math.isnan(rp) or math.isnan(rb) or rb - rp <= margin:
        return previous
    return best
