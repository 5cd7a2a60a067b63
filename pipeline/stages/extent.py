"""The target's extent from its colour: the pixels whose colour is likelier on the target than
around it.

A box that keeps the first frame's aspect misses what a walking person's legs, a turning car or
a cyclist's wheels add to it; the correlation filter's scale estimate is isotropic and the IR
contour is often rejected. This stage measures the extent directly, as the colour trackers'
segmentations do (the object/surround likelihood of Possegger et al. 2015, DAT, and Bertinetto
et al. 2016, Staple):

1. the object histogram is the target's model ``q`` (its kernel histogram); the surround
   histogram ``b`` is that of the pixels of the search region outside the target's box grown by
   ``gap_fraction``;
2. a pixel is the target's when its bin is ``likelihood_ratio`` times likelier under ``q`` than
   under ``b`` (``q_u >= r b_u``);
3. the extent is the box of the connected set of such pixels around the centre, inside the box
   grown by ``window_fraction`` of the target's mean size (``sqrt(w h)``) on every side, after a
   closing; trimmed by ``trim_fraction`` of its
   pixels on each side so that a stray spur does not widen it.

It is refused (None) when too few pixels are the target's, when the set reaches the window's
edge (the colour does not tell the target from its surround there), or when the extent differs
from the current size by more than ``max_ratio`` along either axis. The dual tracker does not
measure it where another target lies within the window (a neighbour of like colours would be
taken for the target's own part).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import cv2
import numba
import numpy as np

from pipeline.params import Section, param
from pipeline.stages._labels import components, counts_in_rect, label_profiles
from pipeline.stages._labels import warm_up as labels_warm_up
from pipeline.types import BBox


@dataclass(frozen=True)
class ExtentConfig(Section):
    """The colour extent measurement.

    Parameters
    ----------
    gap_fraction : float
        The surround starts this share of the box's size beyond the box on every side, in [0, 1];
        default 0.25 (the part of a target the box misses is not counted as surround).
    likelihood_ratio : float
        A pixel is the target's when its colour is this many times likelier on the target than
        in the surround, >= 1; default 2. Increasing it keeps a target whose colours the
        background shares from leaking, and drops more of its faint parts.
    window_fraction : float
        The target's pixels are looked for within the box grown by this share of its mean size
        ``sqrt(w h)`` on every side, in [0.1, 1]; default 0.35 (a standing person's box 7 px
        wide and 29 tall grows by 5 px on each side, room for its legs to spread).
    min_fill : float
        Fewest target pixels, as a share of the box's area, in [0, 1]; default 0.3.
    trim_fraction : float
        Share of the target's pixels left out on each side when its extent is measured, in
        [0, 0.2]; default 0.02.
    max_ratio : float
        An extent more than this factor from the current size along either axis is refused, > 1;
        default 1.8.
    """

    section = "extent"

    gap_fraction: float = param(0.25, ge=0, le=1)
    likelihood_ratio: float = param(2.0, ge=1)
    window_fraction: float = param(0.35, ge=0.1, le=1)
    min_fill: float = param(0.3, ge=0, le=1)
    trim_fraction: float = param(0.02, ge=0, le=0.2)
    max_ratio: float = param(1.8, gt=1)


def surround_histogram(
    bins: np.ndarray, box: BBox, gap_fraction: float, n_bins: int
) -> np.ndarray:
    """Normalised histogram of the pixels of ``bins`` outside ``box`` grown by ``gap_fraction`` of
    its size per side (``box`` in ``bins`` px; zeros when there is none)."""
    H, W = bins.shape
    gx, gy = gap_fraction * box.w, gap_fraction * box.h
    x0, y0 = max(int(np.floor(box.x - gx)), 0), max(int(np.floor(box.y - gy)), 0)
    x1, y1 = min(int(np.ceil(box.x2 + gx)), W), min(int(np.ceil(box.y2 + gy)), H)
    h = np.bincount(bins.ravel(), minlength=n_bins).astype(np.float64)
    if x1 > x0 and y1 > y0:
        h -= np.bincount(bins[y0:y1, x0:x1].ravel(), minlength=n_bins)
    s = h.sum()
    return h / s if s > 0 else h


def target_mask(
    bins: np.ndarray, q: np.ndarray, surround: np.ndarray, likelihood_ratio: float
) -> np.ndarray:
    """uint8 0/1: the pixels whose bin is ``likelihood_ratio`` times likelier under ``q`` than
    under ``surround``."""
    keep = (q > 0) & (q >= likelihood_ratio * surround)
    return keep[bins].astype(np.uint8)


def trimmed_range(counts: np.ndarray, trim_fraction: float) -> tuple[float, float]:
    """The ``100 trim_fraction`` and ``100 (1 - trim_fraction)`` percentiles of the values ``0, 1,
    ...`` repeated ``counts`` times, as :func:`numpy.percentile` gives them (its linear method)
    without sorting the values.

    >>> trimmed_range(np.array([0, 2, 5, 3]), 0.1)
    (1.0, 3.0)
    """
    lo, hi = _trimmed_range(np.asarray(counts, np.int64), float(trim_fraction))
    return float(lo), float(hi)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _trimmed_range(counts, trim_fraction):  # pragma: no cover (compiled)
    """:func:`trimmed_range` compiled: the same float64 operations as numpy's percentile."""
    n = 0
    for v in counts:
        n += v
    cum = np.cumsum(counts)
    out = np.empty(2, np.float64)
    qs = ((100.0 * trim_fraction) / 100.0, (100.0 * (1.0 - trim_fraction)) / 100.0)
    for i in range(2):
        at = qs[i] * (n - 1)
        k = int(np.floor(at))
        a = float(np.searchsorted(cum, k, side="right"))
        b = float(np.searchsorted(cum, min(k + 1, n - 1), side="right"))
        t = at - k
        # numpy's _lerp, so that the values equal np.percentile's to the last bit
        d = b - a
        out[i] = b - d * (1 - t) if t >= 0.5 else a + d * t
    return out[0], out[1]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _window_mask(
    bins, q, gx0, gy0, gx1, gy1, x0, y0, x1, y1, ratio
):  # pragma: no cover (compiled)
    """:func:`surround_histogram` (outside the grown box ``[gx0, gx1) x [gy0, gy1)``) and
    :func:`target_mask` of the window ``[x0, x1) x [y0, y1)`` in one pass: the counts are whole
    numbers, so the sums are numpy's exactly."""
    H, W = bins.shape
    n_bins = q.size
    h = np.zeros(n_bins, np.float64)
    for r in range(H):
        for c in range(W):
            h[bins[r, c]] += 1.0
    if gx1 > gx0 and gy1 > gy0:
        for r in range(gy0, gy1):
            for c in range(gx0, gx1):
                h[bins[r, c]] -= 1.0
    s = 0.0
    for u in range(n_bins):
        s += h[u]
    keep = np.zeros(n_bins, np.uint8)
    for u in range(n_bins):
        b = h[u] / s if s > 0 else h[u]
        keep[u] = 1 if (q[u] > 0 and q[u] >= ratio * b) else 0
    out = np.empty((y1 - y0, x1 - x0), np.uint8)
    for r in range(y0, y1):
        for c in range(x0, x1):
            out[r - y0, c - x0] = keep[bins[r, c]]
    return out


def search_window(box: BBox, cfg: ExtentConfig) -> BBox:
    """Where :func:`colour_extent` looks for the target's pixels: ``box`` grown by
    ``window_fraction`` of its mean size on every side."""
    grow = cfg.window_fraction * float(np.sqrt(max(box.w * box.h, 0.0)))
    return BBox(box.x - grow, box.y - grow, box.w + 2 * grow, box.h + 2 * grow)


def colour_extent(bins: np.ndarray, q: np.ndarray, box: BBox, cfg: ExtentConfig) -> BBox | None:
    """The target's extent (``bins`` px) around ``box`` (``bins`` px, the current estimate), or
    None.

    Parameters
    ----------
    bins : (H, W) int array
        Bin index of every pixel of a region around the target (the mean-shift search region).
    q : (n_bins,) float array
        The target's normalised colour model.
    box : BBox
        The target's current box in the region's px.
    cfg : ExtentConfig

    Examples
    --------
    A 6 x 12 target of bin 1 on a background of bin 0, given as a 6 x 6 box at its top:

    >>> import numpy as np
    >>> from pipeline.types import BBox
    >>> bins = np.zeros((40, 40), np.int32); bins[10:22, 17:23] = 1
    >>> q = np.array([0.0, 1.0])
    >>> e = colour_extent(bins, q, BBox(17, 10, 6, 10), ExtentConfig(trim_fraction=0.0))
    >>> (e.x, e.y, e.w, e.h)
    (17.0, 10.0, 6.0, 12.0)
    """
    H, W = bins.shape
    if box.w < 2 or box.h < 2:
        return None
    win = search_window(box, cfg)
    x0, y0 = max(int(np.floor(win.x)), 0), max(int(np.floor(win.y)), 0)
    x1, y1 = min(int(np.ceil(win.x2)), W), min(int(np.ceil(win.y2)), H)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return None
    # surround_histogram and target_mask in one compiled pass
    gx, gy = cfg.gap_fraction * box.w, cfg.gap_fraction * box.h
    mask = _window_mask(
        bins,
        np.asarray(q, np.float64),
        max(int(np.floor(box.x - gx)), 0),
        max(int(np.floor(box.y - gy)), 0),
        min(int(np.ceil(box.x2 + gx)), W),
        min(int(np.ceil(box.y2 + gy)), H),
        x0,
        y0,
        x1,
        y1,
        float(cfg.likelihood_ratio),
    )
    k = max(round(0.15 * min(box.w, box.h)) | 1, 3)
    pad = cv2.copyMakeBorder(
        mask, k, k, k, k, cv2.BORDER_CONSTANT, value=0
    )  # no closing through the border
    mask = cv2.morphologyEx(
        pad, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
    )[k:-k, k:-k]
    mask = np.ascontiguousarray(mask)
    n, lab, stats, _ = components(mask)
    if n < 2:
        return None
    # the component holding most of the target's pixels inside the current box
    ix0, iy0 = max(int(box.x) - x0, 0), max(int(box.y) - y0, 0)
    ix1, iy1 = (
        max(min(int(np.ceil(box.x2)) - x0, x1 - x0), ix0 + 1),
        max(min(int(np.ceil(box.y2)) - y0, y1 - y0), iy0 + 1),
    )
    inner = counts_in_rect(lab, n, ix0, iy0, ix1, iy1)
    j = int(np.argmax(inner))
    if inner[j] == 0 or stats[j, cv2.CC_STAT_AREA] < cfg.min_fill * box.area:
        return None
    sx, sy, sw, sh = (
        int(stats[j, k])
        for k in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT)
    )
    # a set that reaches the window's edge (where the frame does not end) leaks into the surround
    if (
        (sx == 0 and x0 > 0)
        or (sy == 0 and y0 > 0)
        or (sx + sw == x1 - x0 and x1 < W)
        or (sy + sh == y1 - y0 and y1 < H)
    ):
        return None
    cols, rows = label_profiles(lab, j)  # the component's pixels per column and per row
    if cfg.trim_fraction > 0:
        ex0, ex1 = trimmed_range(cols, cfg.trim_fraction)
        ey0, ey1 = trimmed_range(rows, cfg.trim_fraction)
        ex1, ey1 = ex1 + 1, ey1 + 1
    else:
        (cx,), (cy,) = np.nonzero(cols), np.nonzero(rows)
        ex0, ex1, ey0, ey1 = cx[0], cx[-1] + 1, cy[0], cy[-1] + 1
    out = BBox(float(ex0 + x0), float(ey0 + y0), float(ex1 - ex0), float(ey1 - ey0))
    r = cfg.max_ratio
    if not (1 / r <= out.w / box.w <= r and 1 / r <= out.h / box.h <= r):
        return None
    return out


@cache
def warm_up() -> None:
    """Compile (first run) or load from numba's cache the extent's kernels once per process, for
    the argument types the tracker passes (colour bins int32, intensity bins uint8; labels
    int32)."""
    for dtype in (np.int32, np.uint8):
        bins = np.zeros((6, 6), dtype)
        _window_mask(bins, np.ones(2), 1, 1, 4, 4, 0, 0, 6, 6, 2.0)
    labels_warm_up()
    _trimmed_range(np.arange(4, dtype=np.int64), 0.02)
